"""Interval estimates for the mismatch study: statistics of episodes grouped by training seed.

A cell of the study holds one metric's values in an array ``(seeds, episodes)``: row s is the
agent trained with seed s, column k the evaluation episode k (the same episodes for every row).
A deterministic controller (computed torque, PD) has one row.  Some metrics are undefined in
some episodes (NaN, e.g. the settling time of an episode that never settles).

* :func:`iqm`: the interquartile mean, the mean of the middle half of the values (25 % trimmed
  from each end, as ``scipy.stats.trim_mean(x, 0.25)``).  Agarwal et al., "Deep reinforcement
  learning at the edge of the statistical precipice" (NeurIPS 2021, the rliable library),
  recommend it for RL results: a few failed episodes dominate a mean, and a median ignores all
  but one or two values.
* :func:`stratified_bootstrap`: the percentile bootstrap of a statistic over a two-level
  sample: each resample draws the seeds with replacement, then within each drawn seed its
  episodes with replacement (the stratified, hierarchical bootstrap of rliable's
  ``StratifiedBootstrap`` over runs, here with episodes as the inner level).  So the interval
  covers both sources of variation: another set of evaluation episodes, and another set of
  training seeds.
* :func:`paired_difference`: the same for the difference of a statistic between two cells
  measured on the same episodes: one set of drawn indices serves both, so what the two cells
  share (the episodes' difficulty) cancels in each resample.
* :func:`double_difference`: the same for a difference of two such differences, each within one
  controller (its cell on one plant minus its cell on another): what a controller built on one
  model loses moving between plants, beyond what the controller built on another loses on the
  same move.  Each controller's seeds are paired with themselves, so the spread between
  training seeds largely cancels.
* :func:`resolved`: whether an interval excludes zero.
* :func:`seeds_to_resolve`: for an unresolved difference between learned rows, about how many
  training seeds per row would resolve a difference of a given size (by default its estimate).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from stewart_env.validation import integer

#: Bootstrap resamples of every interval: percentile bounds of a 95 % interval then move by
#: about 0.1 of the interval's width between seeds of the resampling (Efron & Tibshirani 1993).
RESAMPLES = 2000
CONFIDENCE = 0.95
#: The seed of the resampling, so that an interval is reproducible.
BOOTSTRAP_SEED = 0
#: The statistics a cell can report, by name.
STATISTICS = ("mean", "iqm")


def _as_cell(values) -> np.ndarray:
    """``values`` as a float array (seeds, episodes); a 1-d array is one seed."""
    a = np.asarray(values, dtype=float)
    if a.ndim == 1:
        a = a[None, :]
    if a.ndim != 2 or a.size == 0:
        raise ValueError(f"values: expected a non-empty array (seeds, episodes) or (episodes,), got shape {a.shape}")
    return a


def _along_last(values: np.ndarray, statistic: str) -> np.ndarray:
    """``statistic`` ("mean" or "iqm") of ``values`` along the last axis, NaNs left out; NaN
    where a slice has no finite value.  The IQM drops floor(n / 4) values from each end of the n
    finite ones, as ``scipy.stats.trim_mean(x, 0.25)``."""
    if statistic not in STATISTICS:
        raise ValueError(f"statistic: expected one of {', '.join(STATISTICS)}, got {statistic!r}")
    finite = np.isfinite(values)
    n = finite.sum(axis=-1)
    if statistic == "mean":
        total = np.where(finite, values, 0.0).sum(axis=-1)
    else:
        ordered = np.sort(np.where(finite, values, np.inf), axis=-1)  # NaNs last, as +inf
        cut = (n // 4)[..., None]
        position = np.arange(values.shape[-1])
        keep = (position >= cut) & (position < n[..., None] - cut)
        total = np.where(keep, ordered, 0.0).sum(axis=-1)
        n = keep.sum(axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n > 0, total / np.maximum(n, 1), np.nan)


def iqm(values) -> float:
    """Interquartile mean of the finite values (all seeds and episodes pooled).

    Args:
        values: the values, of any shape.

    Returns:
        The mean of the middle half of the finite values; NaN if none.

    Examples:
        >>> from stewart_env.agents.evaluation.statistics import iqm
        >>> iqm([1.0, 2.0, 3.0, 4.0, 100.0, float("nan")])
        3.0
    """
    return float(_along_last(np.asarray(values, dtype=float).ravel(), "iqm"))


def point_estimate(values, statistic: str) -> float:
    """A statistic of a cell's finite values, seeds and episodes pooled.

    Args:
        values: the cell (seeds, episodes), or (episodes,).
        statistic: ``"mean"`` or ``"iqm"``.

    Returns:
        The statistic (NaN if no value is finite).
    """
    return float(_along_last(_as_cell(values).ravel(), statistic))


def _resample_indices(
    shape: tuple[int, int], resamples: int, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """Stratified draws for a cell (seeds S, episodes K): seed indices (B, S, 1) with replacement,
    and for each drawn seed episode indices (B, S, K) with replacement."""
    seeds, episodes = shape
    s = rng.integers(0, seeds, size=(resamples, seeds, 1))
    k = rng.integers(0, episodes, size=(resamples, seeds, episodes))
    return s, k


@dataclass(frozen=True)
class Interval:
    """A point estimate and its bootstrap interval [low, high].

    Attributes:
        estimate: the statistic of the whole sample.
        low, high: the interval's bounds.
        seeds, episodes: the sample it was computed from.
        n: how many of its values were finite (None: not recorded).
    """

    estimate: float
    low: float
    high: float
    seeds: int
    episodes: int
    n: int | None = None

    @property
    def resolved(self) -> bool:
        """Whether the interval excludes zero (see :func:`resolved`)."""
        return resolved(self.low, self.high)


def resolved(low: float, high: float) -> bool:
    """Whether the interval [low, high] excludes zero: a difference whose sign the sample determines.

    Args:
        low: the interval's lower bound; an undefined bound (NaN) resolves nothing.
        high: the interval's upper bound.

    Returns:
        True if both bounds are finite and of one sign.
    """
    return bool(np.isfinite(low) and np.isfinite(high) and (low > 0 or high < 0))


def seeds_to_resolve(interval: Interval, effect: float | None = None) -> int | None:
    """About how many training seeds per row would make an unresolved interval exclude zero.

    An interval's width shrinks as 1 / sqrt(seeds) when the seeds dominate it, so seeds
    (half-width / effect)^2, rounded up.  A planning figure, not a promise: with few seeds the width
    is rough, and an estimate from few seeds may be mostly their spread (pass a better-measured
    ``effect`` then).

    Args:
        interval: the unresolved interval.
        effect: the size of the difference to resolve (default: the interval's own estimate).

    Returns:
        The number of seeds; None where the interval is resolved, rests on one seed (the width
        then shrinks with episodes), or the effect is zero or undefined.
    """
    half_width = 0.5 * (interval.high - interval.low)
    effect = abs(interval.estimate if effect is None else effect)
    if interval.resolved or interval.seeds < 2 or not np.isfinite(half_width) or not np.isfinite(effect) or not effect:
        return None
    # rounded down first where the ratio is a whole number but for the last bits
    return int(np.ceil(np.round(interval.seeds * (half_width / effect) ** 2, 9)))


def _percentiles(samples: np.ndarray, confidence: float) -> tuple[float, float]:
    finite = samples[np.isfinite(samples)]
    if finite.size == 0:
        return float("nan"), float("nan")
    tail = 50.0 * (1.0 - confidence)
    low, high = np.percentile(finite, [tail, 100.0 - tail])
    return float(low), float(high)


def _check(confidence: float, resamples: int) -> None:
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence: expected a number in (0, 1), got {confidence!r}")
    integer("resamples", resamples, 1, 10**7)  # 10^7 resamples of a cell already take minutes


def _bootstrap(
    cells: list[np.ndarray],
    combine: Callable[..., np.ndarray],
    statistic: str,
    confidence: float,
    resamples: int,
    seed: int,
) -> Interval:
    """The percentile interval of ``combine(stat(cell_1*), stat(cell_2*), ...)`` over stratified
    resamples drawn once for all cells (they share the shape (seeds, episodes))."""
    _check(confidence, resamples)
    shape = cells[0].shape
    if any(c.shape != shape for c in cells):
        raise ValueError(f"values: paired cells need one shape (seeds, episodes), got {[c.shape for c in cells]}")
    s, k = _resample_indices(shape, int(resamples), np.random.default_rng(seed))
    drawn = [_along_last(c[s, k].reshape(int(resamples), -1), statistic) for c in cells]
    estimate = float(combine(*[_along_last(c.ravel(), statistic) for c in cells]))
    low, high = _percentiles(combine(*drawn), confidence)
    n = min(int(np.isfinite(c).sum()) for c in cells)
    return Interval(estimate, low, high, shape[0], shape[1], n)


def double_difference(
    values,
    values_home,
    reference,
    reference_home,
    statistic: str = "mean",
    confidence: float = CONFIDENCE,
    resamples: int = RESAMPLES,
    seed: int = BOOTSTRAP_SEED,
) -> Interval:
    """``stat(values - values_home) - stat(reference - reference_home)`` and its stratified bootstrap
    interval (:func:`paired_difference` of the two changes).

    Each controller's change between plants is taken seed by seed and episode by episode before
    the statistic, so what an episode of a seed shares on both plants (the seed's own bias, the
    episode's difficulty) cancels; the statistic is then that of the changes (the IQM: the typical
    episode's change).

    Args:
        values: one controller's cell (seeds, episodes) on a plant.
        values_home: the same controller's cell on its home plant.
        reference: another controller's cell on the first plant.
        reference_home: that controller's cell on the home plant.
        statistic: ``"mean"`` or ``"iqm"`` (:data:`STATISTICS`).
        confidence: the interval's confidence level, in (0, 1).
        resamples: the number of bootstrap resamples.
        seed: the resampling's seed: the same seed gives the same interval.

    Returns:
        The :class:`Interval`.

    Raises:
        ValueError: an unknown statistic, or a bad confidence or resamples count.
    """
    return paired_difference(
        _as_cell(values) - _as_cell(values_home),
        _as_cell(reference) - _as_cell(reference_home),
        statistic,
        confidence,
        resamples,
        seed,
    )


def stratified_bootstrap(
    values,
    statistic: str = "mean",
    confidence: float = CONFIDENCE,
    resamples: int = RESAMPLES,
    seed: int = BOOTSTRAP_SEED,
) -> Interval:
    """Point estimate and percentile bootstrap interval of a statistic of one cell.

    Each of ``resamples`` resamples draws the seeds with replacement and, within each drawn seed,
    its episodes with replacement; NaN values are left out of each resample's statistic.

    Args:
        values: the cell, (seeds, episodes), or (episodes,) for one seed.
        statistic: ``"mean"`` or ``"iqm"`` (:data:`STATISTICS`).
        confidence: the interval's confidence level, in (0, 1).
        resamples: the number of bootstrap resamples.
        seed: the resampling's seed: the same seed gives the same interval.

    Returns:
        The :class:`Interval` (estimate, low, high and the cell's sizes).

    Raises:
        ValueError: an unknown statistic, a confidence outside (0, 1) or a resamples count
            outside [1, 10^7].

    Examples:
        >>> import numpy as np
        >>> from stewart_env.agents.evaluation.statistics import stratified_bootstrap
        >>> cell = np.arange(12.0).reshape(3, 4)       # 3 training seeds, 4 episodes each
        >>> interval = stratified_bootstrap(cell, "iqm")
        >>> print(round(interval.estimate, 2), interval.seeds, interval.episodes)
        5.5 3 4
        >>> bool(interval.low < interval.estimate < interval.high)
        True
    """
    return _bootstrap([_as_cell(values)], lambda a: a, statistic, confidence, resamples, seed)


def paired_difference(
    values,
    reference,
    statistic: str = "mean",
    confidence: float = CONFIDENCE,
    resamples: int = RESAMPLES,
    seed: int = BOOTSTRAP_SEED,
) -> Interval:
    """``statistic(values) - statistic(reference)`` and its stratified bootstrap interval.

    The two cells are resampled with the same indices: episode k of ``values`` and of
    ``reference`` are the same seeded episode, and seed s of each is drawn together.

    Args:
        values: the cell (seeds, episodes) whose statistic is taken first.
        reference: the cell (seeds, episodes) subtracted, its episodes paired with ``values``'s.
        statistic: ``"mean"`` or ``"iqm"`` (:data:`STATISTICS`).
        confidence: the interval's confidence level, in (0, 1).
        resamples: the number of bootstrap resamples.
        seed: the resampling's seed: the same seed gives the same interval.

    Returns:
        The :class:`Interval`.

    Raises:
        ValueError: an unknown statistic, or a bad confidence or resamples count.

    Examples:
        >>> import numpy as np
        >>> from stewart_env.agents.evaluation.statistics import paired_difference
        >>> reference = np.arange(12.0).reshape(3, 4)
        >>> interval = paired_difference(reference + 1.0, reference)
        >>> round(interval.estimate, 6), round(interval.low, 6), round(interval.high, 6), interval.resolved
        (1.0, 1.0, 1.0, True)
    """
    return _bootstrap([_as_cell(values), _as_cell(reference)], np.subtract, statistic, confidence, resamples, seed)


def share_removed(
    values,
    remaining,
    reference,
    statistic: str = "mean",
    confidence: float = CONFIDENCE,
    resamples: int = RESAMPLES,
    seed: int = BOOTSTRAP_SEED,
) -> Interval:
    """``[stat(values) - stat(remaining)] / [stat(values) - stat(reference)]`` and its stratified
    bootstrap interval, the three cells (seeds, episodes) resampled with the same indices: the share
    of the cost ``values - reference`` that a controller with ``remaining`` removes (1: all of it,
    0: none, negative: it costs more).  Unstable where the cost's own interval includes zero.

    Args:
        values: the costly controller's cell (seeds, episodes).
        remaining: the cell of the controller whose cost share is measured.
        reference: the cell of the controller without the cost.
        statistic: ``"mean"`` or ``"iqm"`` (:data:`STATISTICS`).
        confidence: the interval's confidence level, in (0, 1).
        resamples: the number of bootstrap resamples.
        seed: the resampling's seed: the same seed gives the same interval.

    Returns:
        The :class:`Interval`.

    Raises:
        ValueError: an unknown statistic, or a bad confidence or resamples count.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        return _bootstrap(
            [_as_cell(values), _as_cell(remaining), _as_cell(reference)],
            lambda c, r, e: (c - r) / (c - e),
            statistic,
            confidence,
            resamples,
            seed,
        )
