"""How a log's forces relate to their time stamps (``LogSettings.forces``), and the consistent
fit's prior weight chosen by a score (``identify_log``'s ``score``)."""

import numpy as np
import pytest

import stewart_env as se
from stewart_env.identification import excitation as exc
from stewart_env.identification import log as logs
from stewart_env.identification import logged
from stewart_env.identification.base import IdentificationError

RATE = 200.0


@pytest.fixture(scope="module")
def held_log():
    """8 s of a random excitation of dasgupta1998 whose forces a drive holds from each stamp to
    the next: each logged force is the exact inverse dynamics half a period after its stamp, the
    middle of its hold (the hold's mean, to second order in the period)."""
    params = se.load_platform("dasgupta1998")
    model = se.make_dynamics("improved", params)
    series = exc.random_excitation(params, model, np.random.default_rng(3), period=6.0, harmonics=5)
    stamps = 0.5 + np.arange(int(8 * RATE) + 1) / RATE

    def states(times):
        return exc.task_states(*series.sample(times))

    t, R, v, w, a, alpha = states(stamps)
    forces = model.inverse(*states(stamps + 0.5 / RATE))
    header = {"format": logs.FORMAT, "kind": "record", "platform": "dasgupta1998", "rate_hz": str(RATE)}
    data = {
        "time": stamps,
        "pose": np.concatenate([t, se.matrix_to_rpy(R)], axis=1),
        "twist": np.concatenate([v, w], axis=1),
        "acceleration": np.concatenate([a, alpha], axis=1),
        "leg_force": forces,
    }
    return params, logs.Log(header, data, "held.csv")


@pytest.mark.slow
def test_held_forces_read_as_held_fit_the_motion_they_drove(held_log):
    params, log = held_log
    errors = {}
    for forces in logged.FORCES:
        report = logged.identify_log(log, params, logged.LogSettings(derivatives="exact", forces=forces))["report"]
        errors[forces] = report["held_out_force_error"]["wls"]
        assert report["settings"]["forces"] == forces
    # read as sampled, the forces lead the motion by half a period, an error of (dt / 2) dF/dt;
    # read as held, the mean of two samples leaves (dt / 2)^2 / 2 of d2F/dt2: orders of magnitude less
    assert errors["held"] < 1e-2 * errors["sampled"]
    assert errors["sampled"] > 0.01  # N: the lead is no rounding error


@pytest.mark.slow
def test_the_prior_weight_is_the_one_of_the_lowest_score(held_log):
    params, log = held_log
    scores = iter([2.0, 1.0, 3.0])
    seen = []

    def score(identified):
        seen.append(identified.platform.mass)
        return next(scores)

    settings = logged.LogSettings(derivatives="exact", forces="held", prior_weight=(1e-4, 1e-2, 1e-1))
    report = logged.identify_log(log, params, settings, score=score)["report"]
    assert len(seen) == 3  # each weight's identified platform scored once
    assert report["settings"]["prior_weight"] == 1e-2
    assert [c["prior_weight"] for c in report["prior_weights"]] == [1e-4, 1e-2, 1e-1]
    assert [c["score"] for c in report["prior_weights"]] == [2.0, 1.0, 3.0]
    assert "prior weight 0.01" in logged.markdown(report)


@pytest.mark.parametrize(
    ("settings", "score", "message"),
    [
        (logged.LogSettings(forces="zoh"), None, "--forces: expected sampled or held, got 'zoh'"),
        (logged.LogSettings(prior_weight=(1e-3, 1e-2)), None, "prior_weight: several weights need a score"),
        (logged.LogSettings(prior_weight=-1.0), None, "--prior-weight: expected positive numbers, got -1.0"),
        (logged.LogSettings(prior_weight=()), lambda p: 0.0, "--prior-weight: expected positive numbers, got ()"),
    ],
)
def test_a_bad_force_timing_or_prior_weight_is_named(dasgupta, settings, score, message):
    log = logs.Log({"kind": "record"}, {}, "rec.csv")  # the settings are checked before the log's data
    with pytest.raises(IdentificationError, match=message.replace("(", r"\(").replace(")", r"\)")):
        logged.identify_log(log, dasgupta, settings, score=score)
