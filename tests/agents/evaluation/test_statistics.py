"""The study's statistics: IQM against hand values, the stratified bootstrap against hand-computed
resamples and known distributions, and the resolved/unresolved decision."""

import numpy as np
import pytest

from stewart_env.agents.evaluation.statistics import (
    Interval,
    iqm,
    paired_difference,
    point_estimate,
    resolved,
    seeds_to_resolve,
    stratified_bootstrap,
)


def test_iqm_of_known_arrays():
    assert iqm(np.arange(8.0)) == 3.5  # drops 0, 1 and 6, 7: mean of 2..5
    assert iqm([1.0, 2.0, 3.0, 1000.0]) == 2.5  # the outlier is trimmed
    assert iqm([5.0, 1.0, 3.0]) == 3.0  # n < 4 trims nothing: the mean
    assert iqm([np.nan, 1.0, 2.0, 3.0, 4.0]) == 2.5  # NaN left out: IQM of 1..4
    assert np.isnan(iqm([np.nan, np.nan]))
    # a cell (seeds, episodes) pools its values
    assert point_estimate([[0.0, 1.0, 2.0, 3.0], [4.0, 5.0, 6.0, 7.0]], "iqm") == 3.5
    assert point_estimate([[1.0, np.nan], [3.0, 5.0]], "mean") == 3.0


def test_iqm_matches_scipy_trim_mean():
    stats = pytest.importorskip("scipy.stats")
    rng = np.random.default_rng(1)
    for n in (4, 5, 7, 10, 33):
        x = rng.standard_cauchy(n)
        assert iqm(x) == pytest.approx(stats.trim_mean(x, 0.25), rel=1e-12)  # the same sum in another order


def test_bootstrap_matches_a_hand_computed_resampling():
    """The interval is the percentiles of the statistic over resamples that draw seeds, then
    episodes within each drawn seed, with the documented generator."""
    cell = np.array([[1.0, 2.0, 4.0], [10.0, 20.0, 40.0]])
    got = stratified_bootstrap(cell, "mean", resamples=50, seed=7)
    rng = np.random.default_rng(7)
    s = rng.integers(0, 2, size=(50, 2, 1))
    k = rng.integers(0, 3, size=(50, 2, 3))
    means = [np.mean([cell[s[b, i, 0], k[b, i, j]] for i in range(2) for j in range(3)]) for b in range(50)]
    low, high = np.percentile(means, [2.5, 97.5])
    assert got.estimate == pytest.approx(77.0 / 6.0, rel=1e-15)  # a mean of six small floats: last-bit rounding
    assert (got.low, got.high) == pytest.approx((low, high), rel=1e-12)  # the same numbers summed in another order
    assert (got.seeds, got.episodes, got.n) == (2, 3, 6)
    assert stratified_bootstrap([1.0, np.nan, 3.0]).n == 2  # the values it rests on


def test_bootstrap_is_reproducible_and_depends_on_its_seed():
    x = np.random.default_rng(3).normal(size=(3, 10))
    assert stratified_bootstrap(x, "iqm", seed=5) == stratified_bootstrap(x, "iqm", seed=5)
    assert stratified_bootstrap(x, "iqm", seed=5).low != stratified_bootstrap(x, "iqm", seed=6).low


def test_bootstrap_interval_covers_the_truth_at_about_its_level():
    """Normal episodes (mean 1, sd 0.5) around seed means N(0, 0.3): the 95 % interval of the mean
    covers the true mean 1.0 in most of 200 independent studies of 5 seeds x 20 episodes."""
    rng = np.random.default_rng(0)
    covered = 0
    for trial in range(200):
        seed_means = 1.0 + rng.normal(0.0, 0.3, size=(5, 1))
        cell = seed_means + rng.normal(0.0, 0.5, size=(5, 20))
        ci = stratified_bootstrap(cell, "mean", resamples=500, seed=trial)
        covered += ci.low <= 1.0 <= ci.high
    # the percentile bootstrap of 5 seeds under-covers (about 0.83-0.90 for 5 clusters); far from
    # the 0.5 an interval of the episodes alone would reach here, and not above 0.99
    assert 0.78 <= covered / 200 <= 0.99


def test_interval_narrows_with_more_episodes():
    rng = np.random.default_rng(2)
    small = stratified_bootstrap(rng.normal(size=10), "mean")
    large = stratified_bootstrap(rng.normal(size=1000), "mean")
    # width ~ 4 sd / sqrt(n): 1.24 at n = 10, 0.124 at n = 1000; a factor 10 +- sampling noise
    assert 5 < (small.high - small.low) / (large.high - large.low) < 20


def test_paired_difference_cancels_what_the_cells_share():
    """Two controllers on the same 30 episodes, whose difficulty varies 100 times more than the
    constant 0.01 between them: paired, the difference is resolved; the difficulty cancels."""
    difficulty = np.random.default_rng(4).lognormal(0.0, 1.0, size=30)
    worse, exact = difficulty + 0.01, difficulty
    d = paired_difference(worse, exact, "mean")
    assert d.estimate == pytest.approx(0.01, rel=1e-9)  # float rounding of sums of order 30
    # each resample's difference is 0.01 up to rounding of values near 10: percentiles agree far within 1e-6
    assert d.resolved and d.low == pytest.approx(0.01, rel=1e-6) and d.high == pytest.approx(0.01, rel=1e-6)
    # the same values as unrelated samples: their intervals overlap, nothing is resolved
    a, b = stratified_bootstrap(worse), stratified_bootstrap(exact)
    assert a.low < b.high
    same = paired_difference(exact, exact, "iqm")
    assert (same.estimate, same.low, same.high) == (0.0, 0.0, 0.0) and not same.resolved


def test_resolved_decision_on_constructed_intervals():
    assert resolved(0.1, 0.3) and resolved(-0.3, -0.1)
    assert not resolved(-0.1, 0.3) and not resolved(0.0, 0.3) and not resolved(-0.2, 0.0)
    assert not resolved(np.nan, 1.0)
    assert Interval(0.2, 0.1, 0.3, 1, 5).resolved and not Interval(0.2, -0.1, 0.3, 1, 5).resolved


def test_seeds_to_resolve_on_constructed_intervals():
    # half-width 0.3 around 0.1 at 4 seeds: 4 (0.3 / 0.1)^2 = 36 seeds
    assert seeds_to_resolve(Interval(0.1, -0.2, 0.4, 4, 50)) == 36
    assert seeds_to_resolve(Interval(-0.1, -0.35, 0.15, 3, 50)) == 19  # 3 (0.25 / 0.1)^2 = 18.75
    assert seeds_to_resolve(Interval(0.2, 0.1, 0.3, 4, 50)) is None  # already resolved
    assert seeds_to_resolve(Interval(0.1, -0.2, 0.4, 1, 50)) is None  # one seed: episodes, not seeds, narrow it
    assert seeds_to_resolve(Interval(0.0, -0.2, 0.2, 4, 50)) is None  # no estimate to resolve
    assert seeds_to_resolve(Interval(np.nan, np.nan, np.nan, 4, 50)) is None


def test_seeds_to_resolve_follows_the_width_of_more_seeds():
    """The figure rests on the width shrinking as 1 / sqrt(seeds): the same four seeds repeated k
    times keep the estimate, narrow the interval about sqrt(k) times, and so keep the figure;
    repeated to twice the figure, they resolve the difference."""
    rng = np.random.default_rng(3)
    values = 0.15 + np.array([-0.3, 0.1, 0.25, -0.05])[:, None] + rng.normal(0.0, 0.05, (4, 30))
    reference = np.array([0.2, -0.25, 0.0, 0.05])[:, None] + rng.normal(0.0, 0.05, (4, 30))

    def repeated(k):
        return paired_difference(np.tile(values, (k, 1)), np.tile(reference, (k, 1)))

    needed = seeds_to_resolve(repeated(1))
    assert needed is not None and needed > 8
    # the percentile bootstrap's width follows 1 / sqrt(seeds) to within about 15 % here
    assert seeds_to_resolve(repeated(2)) == pytest.approx(needed, rel=0.3)
    assert repeated(-(-2 * needed // 4)).resolved


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"statistic": "median"}, "statistic: expected one of mean, iqm"),
        ({"confidence": 1.5}, "confidence"),
        ({"resamples": 0}, "resamples"),
    ],
)
def test_bad_arguments_are_named(kwargs, message):
    with pytest.raises(ValueError, match=message):
        stratified_bootstrap([1.0, 2.0], **kwargs)


def test_bad_shapes_are_named():
    with pytest.raises(ValueError, match="values: expected a non-empty array"):
        stratified_bootstrap([])
    with pytest.raises(ValueError, match="paired cells need one shape"):
        paired_difference([[1.0, 2.0]], [[1.0, 2.0, 3.0]])
