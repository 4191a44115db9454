"""The reproduction of the case study of He et al. (2018)."""

import os

import numpy as np
import pytest
import yaml

import stewart_env as se
from stewart_env.agents.controllers.pd import PAPER_KD, PAPER_KP, TaskSpacePD
from stewart_env.agents.studies.reproduce import (
    FIGURES,
    reproduce,
    simulate_case_study,
    transient_peaks,
)
from stewart_env.state import PlatformState, Reference
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


#: Samples of the case study (20 ms, dt = 0.2 ms, a sample every 2 ms) as the reproduction computed
#: them with its own Python RK4 loop, before it ran on the compiled rollout: the samples at 10 ms and
#: 20 ms without gravity compensation on ``improved``, at 20 ms with it on ``classical``.
BEFORE_COMPILED_ROLLOUT = {
    ("improved", False): {
        "displacement": [
            [0.0999991293830188, -5.094837245454849e-06, 0.39954088889758643],
            [0.09997472288208525, -5.101890883440652e-06, 0.39996483087143997],
        ],
        "velocity": [
            [-0.010541748405861867, -0.0037248031939872235, 0.21217322702940575],
            [0.0033347518849337313, 0.0016494515166513629, -0.016996741952507752],
        ],
        "angles": [
            [-0.00028675176995290435, 0.0006417922474781951, -0.19998643531482432],
            [3.960040568824596e-05, 4.0258136874332154e-05, -0.2000046309825178],
        ],
        "angular_velocity": [
            [0.04370992238069723, -0.08085782570625716, -0.00244824172075397],
            [-0.003546091937515567, -0.020246412320559168, -0.0005468048247689851],
        ],
        "leg_length": [
            [
                1.4311998158920685,
                1.2062367481361433,
                1.386224635435247,
                1.233951736688183,
                1.2792144211217091,
                1.0918392445912932,
            ],
            [
                1.4316320695917135,
                1.2063052913854133,
                1.3863713516287504,
                1.2343023699049023,
                1.2792546900468102,
                1.0921078737540983,
            ],
        ],
        "leg_rate": [
            [
                0.11725411662139891,
                0.0846795647874946,
                0.08849779386071886,
                0.11288159975423515,
                0.08044467437036777,
                0.13124345990177674,
            ],
            [
                0.00266864275547172,
                -0.010923257835054921,
                -0.009253540665324123,
                0.00031127848053834773,
                -0.013255109738892306,
                -0.013834648648019664,
            ],
        ],
        "leg_force": [
            [
                -628.4553010710993,
                -955.2005888776249,
                -690.0157232432684,
                -802.225515313231,
                -747.609340210182,
                -1148.2192540690116,
            ],
            [
                89.29311975478917,
                228.97164214197673,
                157.60434123915317,
                150.86001671640543,
                162.2123284846629,
                203.3225679750656,
            ],
        ],
    },
    ("classical", True): {
        "displacement": [[0.09996556669604287, -1.1109633048525005e-05, 0.400108808937023]],
        "velocity": [[0.0027955823882990644, 0.0020366543477235476, -0.022198642646525876]],
        "angles": [[0.00012719870213695234, -9.981911074679021e-05, -0.20000302299336267]],
        "angular_velocity": [[0.004166350685202354, -0.03991486880459666, -8.301569742488793e-05]],
        "leg_length": [
            [
                1.4317504507312273,
                1.2063469780983518,
                1.3864193729284746,
                1.2344026376701522,
                1.2792823628348697,
                1.0922023079605319,
            ]
        ],
        "leg_rate": [
            [
                0.007498074509760658,
                -0.017982148177814978,
                -0.012188648824310675,
                0.0028175142493689475,
                -0.021875696619912635,
                -0.014850166751689575,
            ]
        ],
        "leg_force": [
            [
                80.44739149902969,
                246.4513557834619,
                167.00272737629035,
                158.06481319071665,
                171.8623402002216,
                190.0631287611576,
            ]
        ],
    },
}


@pytest.mark.parametrize("model, gravity", list(BEFORE_COMPILED_ROLLOUT))
def test_reproduction_is_unchanged_by_the_compiled_rollout(dasgupta, model, gravity):
    run = simulate_case_study(
        model,
        dasgupta,
        TaskSpacePD(dasgupta, PAPER_KP, PAPER_KD, gravity_compensation=gravity),
        duration=0.02,
        dt=2e-4,
        sample_dt=2e-3,
    )
    samples = [5, 10] if len(BEFORE_COMPILED_ROLLOUT[(model, gravity)]["leg_force"]) == 2 else [10]
    for key, expected in BEFORE_COMPILED_ROLLOUT[(model, gravity)].items():
        expected = np.array(expected)
        # the law now runs compiled (angle rates in closed form instead of a LAPACK solve, fused
        # multiply-adds) and the quaternion comes from Shepperd's method: rounding of 1e-16 that
        # the stiff loop (poles near 300 rad/s) grows to 3e-14 of each quantity's size
        np.testing.assert_allclose(
            getattr(run, key)[samples], expected, rtol=0, atol=1e-12 * np.abs(expected).max(), err_msg=key
        )
    # sample times k * every * dt against k * 2e-3: a few ulps of the 0.02 s end
    np.testing.assert_allclose(run.time, np.arange(11) * 2e-3, rtol=0, atol=1e-15)


def test_recorded_leg_forces_are_the_law_at_the_samples(dasgupta):
    pd = TaskSpacePD(dasgupta, PAPER_KP, PAPER_KD)
    run = simulate_case_study("improved", dasgupta, pd, duration=0.01, dt=2e-4, sample_dt=1e-3)
    case = paper_case(dasgupta)
    target = Reference(case.target_position, se.rpy_to_matrix(case.target_rpy), np.zeros(3), np.zeros(3))
    state = PlatformState(run.displacement, se.rpy_to_matrix(run.angles), run.velocity, run.angular_velocity)
    # the same compiled law on the sampled state; the rotation rebuilt from the angles: rounding
    np.testing.assert_allclose(run.leg_force, pd(state, target), rtol=0, atol=1e-9 * np.abs(run.leg_force).max())


def test_transient_peaks():
    t = np.linspace(0.0, 1.0, 1001)
    q = np.stack(
        [
            1 - np.exp(-5 * t) * np.cos(20 * t),  # overshoot peak near t = pi / 20
            1 - np.exp(-5 * t),  # monotone: the final value
            np.exp(-3 * t) * np.sin(10 * t) - 0.0,  # first extremum near atan(10/3) / 10
        ],
        axis=1,
    )
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
    return params.replace(
        limits=type(lim)(
            (1.0, 1.3), lim.leg_force, lim.position_min, lim.position_max, lim.max_angle, lim.max_condition
        )
    )


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


def test_reproduce_holds_its_out_and_publishes_whole_files(tmp_path, capsys):
    from stewart_env.cli import main
    from stewart_env.files import LOCK_FILE, lock_folder

    out = tmp_path / "out"
    with lock_folder(out):  # another command writing into --out
        assert main(["reproduce", "--out", str(out), "--duration", "0.01"]) == 2
        assert sorted(p.name for p in out.iterdir()) == [LOCK_FILE]  # refused before any file was written
    err = capsys.readouterr().err.strip()
    assert err.startswith(
        f"stewart-env reproduce: error: output directory '{out}' is in use by another "
        f"stewart-env command (PID {os.getpid()})"
    )
    reproduce(out, duration=0.01, progress=False)
    names = sorted(p.name for p in out.iterdir())
    assert [n for n in names if n.startswith(".tmp")] == []  # every file renamed into place, none left half-written
    assert "summary.md" in names and len([n for n in names if n.endswith(".png")]) == 5
