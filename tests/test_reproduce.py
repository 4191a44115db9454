"""The reproduction of the case study of He et al. (2018)."""

import numpy as np
import pytest
import yaml

import stewart_env as se
from stewart_env.agents.pd import PAPER_KD, PAPER_KP, TaskSpacePD
from stewart_env.agents.reproduce import (
    FIGURES,
    reproduce,
    simulate_case_study,
    transient_peaks,
)
from stewart_env.tasks.setpoint import paper_case


def test_short_reproduction_writes_figures_and_summary(tmp_path):
    result = reproduce(tmp_path, duration=0.04, progress=False)
    for name, _, _ in FIGURES:
        assert (tmp_path / name).stat().st_size > 20_000  # a drawn figure, not an empty canvas
    summary = (tmp_path / "summary.md").read_text()
    assert "leg force (N)" in summary and "improved_centroidal" in summary
    # two forms of the same dynamics: they agree to rounding (observed ~1e-13)
    assert result["centroidal_difference"] < 1e-9
    # classical and improved differ at the peaks by percents (the paper's claim), not by rounding
    force = result["differences"]["leg_force"]
    assert 1e-3 < force["peak_difference"] < 1.0
    assert result["differences"]["angular_velocity"]["pointwise_difference"] > 1e-2
    improved = result["runs"]["improved"]
    # the paper's gains lift the platform the 5 mm in ~15 ms; what is left after 40 ms is the sag
    # weight / Kp_z = 480 N / 4e6 N/m = 0.12 mm (the law has no gravity compensation)
    assert np.linalg.norm([0.1, 0.0, 0.4] - improved.displacement[-1]) < 2e-4
    assert "start t0 = (0.1, 0, 0.395) m, rpy0 = (0, 0, -0.2) rad" in summary
    assert "target td = (0.1, 0, 0.4) m" in summary


def test_closed_loop_integrator_matches_the_core_rollout(dasgupta):
    """With a controller that returns constant forces, the closed-loop RK4 is the core's RK4."""
    model = se.make_dynamics("improved", dasgupta)
    start = paper_case(dasgupta)
    rotation = se.rpy_to_matrix(start.start_rpy)
    zero = np.zeros(3)
    forces = model.inverse(start.start_position, rotation, zero, zero, np.array([0.5, -0.3, 2.0]), np.array([1.0, 0, -2]))

    def constant(state, reference):
        return np.broadcast_to(forces, np.shape(state.position)[:-1] + (6,))

    run = simulate_case_study("improved", dasgupta, constant, duration=0.05, dt=1e-3)
    t, R, v, w = se.rollout(model, start.start_position, rotation, zero, zero, forces, dt=1e-3, steps=50)
    # both fourth order with the same step; they differ only in how the rotation is propagated
    # (our quaternion vs the core's), an O(dt^4) difference far below these bounds
    np.testing.assert_allclose(run.displacement[-1], t, atol=1e-9)
    np.testing.assert_allclose(run.velocity[-1], v, atol=1e-8)
    np.testing.assert_allclose(run.angular_velocity[-1], w, atol=1e-7)
    np.testing.assert_allclose(se.rpy_to_matrix(run.angles[-1]), R, atol=1e-9)
    # and the recorded leg forces are the controller's
    np.testing.assert_array_equal(run.leg_force[-1], forces)


def test_transient_peaks():
    t = np.linspace(0.0, 1.0, 1001)
    q = np.stack([
        1 - np.exp(-5 * t) * np.cos(20 * t),  # overshoot peak near t = pi / 20
        1 - np.exp(-5 * t),  # monotone: the final value
        np.exp(-3 * t) * np.sin(10 * t) - 0.0,  # first extremum near atan(10/3) / 10
    ], axis=1)
    values, index = transient_peaks(q)
    assert index[0] == np.argmax(q[:, 0]) and values[0] == q[:, 0].max()
    assert index[1] == 1000 and values[1] == q[-1, 1]
    expected_t = np.arctan(10 / 3) / 10
    assert t[index[2]] == pytest.approx(expected_t, abs=1e-3)  # the grid spacing


def test_reproduction_rejects_bad_steps(dasgupta):
    pd = TaskSpacePD(dasgupta)
    with pytest.raises(ValueError, match="dt"):
        simulate_case_study("improved", dasgupta, pd, duration=0.01, dt=-1e-3)
    with pytest.raises(ValueError, match="sample_dt"):
        simulate_case_study("improved", dasgupta, pd, duration=0.01, dt=2e-4, sample_dt=3e-4)
    with pytest.raises(ValueError, match="duration"):
        simulate_case_study("improved", dasgupta, pd, duration=0.0)


def _short_stroke(params):
    """``params`` with the stroke cut to [1.0, 1.3] m: home (legs 1.26 m) fits, the case (legs up to 1.43 m) not."""
    lim = params.limits
    return params.replace(limits=type(lim)((1.0, 1.3), lim.leg_force, lim.position_min, lim.position_max,
                                           lim.max_angle, lim.max_condition))


def test_paper_case_is_relative_to_home(dasgupta, simulator):
    case = paper_case(dasgupta)
    # the paper's absolute poses: home (0, 0, 0.4) plus the offsets, in float64
    np.testing.assert_allclose(case.start_position, [0.1, 0.0, 0.395], rtol=0, atol=1e-15)
    np.testing.assert_array_equal(case.target_position, [0.1, 0.0, 0.4])
    np.testing.assert_array_equal(case.start_rpy, [0.0, 0.0, -0.2])
    np.testing.assert_array_equal(case.target_rpy, case.start_rpy)
    # on the motion simulator the same offsets from its own home, whose legs stay in its stroke
    moved = paper_case(simulator)
    # (home + offset) - home in float64: the offset up to the rounding of the 2.6 m home height
    np.testing.assert_allclose(moved.start_position - simulator.home_position, [0.1, 0.0, -0.005], atol=1e-15)
    np.testing.assert_allclose(moved.target_position - simulator.home_position, [0.1, 0.0, 0.0], atol=1e-15)
    lo, hi = simulator.limits.leg_length
    for position, rpy in ((moved.start_position, moved.start_rpy), (moved.target_position, moved.target_rpy)):
        lengths, _ = se.inverse_kinematics(simulator, position, se.rpy_to_matrix(rpy))
        assert np.all((lengths > lo) & (lengths < hi))


def test_case_outside_the_stroke_is_refused_naming_platform_and_legs(dasgupta, tmp_path):
    short = _short_stroke(dasgupta)
    with pytest.raises(ValueError) as err:
        paper_case(short)
    message = str(err.value)
    assert repr(short.name) in message and "[1.0, 1.3] m" in message
    # legs 0 and 2 are 1.4296 m and 1.3842 m long at the start pose (1.4317, 1.3864 at the target)
    assert "at the start pose leg 0 is 1.4296 m long" in message
    assert "at the target pose leg 2 is 1.3864 m long" in message
    assert "leg 1 " not in message
    pd = TaskSpacePD(short, PAPER_KP, PAPER_KD)
    with pytest.raises(ValueError, match="leaves the leg stroke"):
        simulate_case_study("improved", short, pd, duration=0.01)
    path = tmp_path / "short.yaml"
    path.write_text(yaml.safe_dump(short.to_dict()))
    with pytest.raises(ValueError, match="leaves the leg stroke"):
        reproduce(tmp_path / "out", platform=str(path), progress=False)
    assert not (tmp_path / "out").exists()
