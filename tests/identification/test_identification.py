"""Dynamic parameter identification: the regressor against inverse dynamics, the base parameters,
the estimators and the identify experiment (docs/physics.md section 5.6,
docs/guides/identification.md)."""

import itertools

import numpy as np
import pytest

import stewart_env as se
from stewart_env.dynamics import kernels as K
from stewart_env.identification import regressor as reg
from stewart_env.params import Damping, RigidBody

from physics_reference import random_state

# every combination of the four switches over both improved forms (classical = joint form + all four)
SWITCH_SETS = [s for n in range(5) for s in itertools.combinations(("c1", "c2", "c3", "c4"), n)]
ALL_MODELS = [
    base + "".join("+" + s for s in switches)
    for base in ("improved", "improved_centroidal")
    for switches in SWITCH_SETS
] + ["classical"]


def random_body(rng, mass_scale):
    """A rigid body with a random positive mass, CoM and a physically valid inertia."""
    m = rng.uniform(0.3, 1.5) * mass_scale
    com = rng.normal(scale=0.05, size=3)
    A = rng.normal(size=(3, 3))
    Q, _ = np.linalg.qr(A)
    inertia = Q @ np.diag(rng.uniform(0.2, 1.0, 3) * 0.01 * mass_scale) @ Q.T
    return RigidBody(mass=m, com=com, inertia=inertia)


def random_params(base, rng):
    """``base`` with every inertial and friction parameter drawn at random, each leg its own."""
    return base.replace(
        platform=random_body(rng, base.platform.mass),
        upper_leg=tuple(random_body(rng, 3.0) for _ in range(6)),
        lower_leg=tuple(random_body(rng, 3.0) for _ in range(6)),
        damping=Damping(*rng.uniform(0.5, 5.0, 3)),
    )


@pytest.mark.parametrize("name", ALL_MODELS)
def test_regressor_times_theta_equals_inverse_dynamics(dasgupta, simulator, rng, name):
    for base in (dasgupta, simulator):
        for _ in range(3):
            params = random_params(base, rng)
            model = se.make_dynamics(name, params)
            t, R, v, w = random_state(params, rng, speed=0.5)
            a, alpha = rng.normal(scale=2.0, size=3), rng.normal(scale=4.0, size=3)
            F = model.inverse(t, R, v, w, a, alpha)
            lhs = se.jacobian(params, t, R).T @ F
            Y = reg.regressor_matrix(model, t, R, v, w, a, alpha)
            rhs = Y @ reg.theta_of(params, model.flags)
            # the same products summed in another order, then a 6x6 solve (cond ~ 10): rounding
            assert np.abs(rhs - lhs).max() < 1e-10 * np.abs(lhs).max()


def test_regressor_is_batched_and_checks_its_arguments(dasgupta, rng):
    model = se.make_dynamics("improved", dasgupta)
    states = [random_state(dasgupta, rng) for _ in range(4)]
    t, R, v, w = (np.stack(x) for x in zip(*states))
    acc = rng.normal(size=(4, 6))
    Y = reg.regressor_matrix(model, t, R, v, w, acc[:, :3], acc[:, 3:])
    assert Y.shape == (4, 6, reg.N_THETA)
    for k in range(4):
        one = reg.regressor_matrix(model, t[k], R[k], v[k], w[k], acc[k, :3], acc[k, 3:])
        assert np.array_equal(Y[k], one)  # each row's arithmetic does not depend on the batch
    with pytest.raises(ValueError, match="lin_acc"):
        reg.regressor_matrix(model, t, R, v, w, acc[:3, :3], acc[:, 3:])
    with pytest.raises(ValueError, match="position"):
        reg.regressor_matrix(model, t[0] * np.nan, R[0], v[0], w[0], acc[0, :3], acc[0, 3:])


def test_theta_round_trips_through_the_bodies(dasgupta, rng):
    params = random_params(dasgupta, rng)
    for flags in (0, K.C3 | K.C4):
        theta = reg.theta_of(params, flags)
        shift_leg, shift_plat = reg.shifts_of(flags)
        m, com, inertia = reg.body_from_theta(theta[:10], shift_plat)
        assert m == pytest.approx(params.platform.mass, rel=1e-14)
        # com = (m c) / m and the parallel-axis term taken off again: rounding
        assert np.allclose(com, params.platform.com, rtol=0, atol=1e-14)
        assert np.allclose(inertia, params.platform.inertia, rtol=0, atol=1e-13)


@pytest.mark.parametrize("name", ["improved", "classical", "improved+c1"])
def test_base_parameters_reproduce_the_regressor_and_leave_a_clear_rank_gap(simulator, rng, name):
    from stewart_env.identification import base

    model = se.make_dynamics(name, simulator)
    b = base.base_parameters(model)
    r = b.rank
    assert 40 < r < reg.N_THETA
    # identifiable columns stay far above the tolerance, the dependent ones at rounding
    assert b.diagonal[r - 1] > 1e3 * base.RANK_TOLERANCE and b.diagonal[r] < 1e-3 * base.RANK_TOLERANCE
    # Y theta == Y_base beta on fresh states, for random parameters: the base parameters carry
    # everything the leg forces see (products of a few hundred terms: rounding)
    params = random_params(simulator, rng)
    theta = reg.theta_of(params, model.flags)
    states = base.random_states(simulator, 20, rng)
    Y = reg.regressor_matrix(model, *states)
    full = Y @ theta
    assert np.abs(b.columns(Y) @ b.of_theta(theta) - full).max() < 1e-10 * np.abs(full).max()
    # and the base parameters map back to a theta with the nominal's unidentifiable part
    nominal = reg.theta_of(simulator, model.flags)
    back = b.theta_from(b.of_theta(theta), nominal)
    assert np.allclose(b.of_theta(back), b.of_theta(theta), rtol=1e-12, atol=1e-12)
    assert np.array_equal(back[b.dependent], nominal[b.dependent])
    assert len(b.names) == r and all(n.split(" ")[0] in reg.THETA_NAMES for n in b.names)


# -- estimators and the experiment ------------------------------------------------------------------

from stewart_env.identification import base as base_mod  # noqa: E402
from stewart_env.identification import estimate as est  # noqa: E402
from stewart_env.identification import excitation as exc  # noqa: E402
from stewart_env.identification import experiment  # noqa: E402
from stewart_env.identification.base import IdentificationError  # noqa: E402


@pytest.fixture(scope="module")
def noise_free(dasgupta):
    """One noise-free record on a perturbed plant: the model, base parameters, the record's
    leg-force rows A and forces, and the truth's base parameters."""
    settings = experiment.Settings(excitation="random", duration=6.0, period=3.0, derivatives="exact", perturb=0.3)
    rng = np.random.default_rng(3)
    truth = experiment.perturbed(dasgupta, settings.perturb, rng)
    plant = se.make_dynamics("improved", truth)
    model = se.make_dynamics("improved", dasgupta)
    base = base_mod.base_parameters(model)
    series = exc.random_excitation(dasgupta, model, rng, period=settings.period)
    record = experiment.measure(
        plant, experiment.simulate(plant, truth, model, series, settings.duration), settings, rng
    )
    A = experiment.rows_of(model, base, record)
    return model, base, A, record, base.of_theta(reg.theta_of(truth, model.flags))


def test_noise_free_data_recover_the_base_parameters_exactly(noise_free):
    model, base, A, record, truth = noise_free
    est.check_rank(A, base)
    for fit in (est.ols(A, record.forces), est.wls(A, record.forces)):
        # exact data and exact derivatives: only rounding, amplified by the regressor's condition
        # number (~1e5 for a random series), separates the estimate from the truth; the drive's
        # Coulomb friction and reflected mass, zero on this plant, come out at ~3e-13 (their columns
        # are of order one), so a zero is judged against 1e-5 of the largest parameter
        scale = np.maximum(np.abs(truth), 1e-5 * np.abs(truth).max())
        assert np.max(np.abs(fit.beta - truth) / scale) < 1e-8


def test_standard_deviations_cover_the_truth_at_their_stated_rate(noise_free):
    model, base, A, record, truth = noise_free
    rng = np.random.default_rng(7)
    T = 300  # a part of the record keeps the repeated fits fast
    A, F = A[-T:], record.true_forces[-T:]
    z = []
    for _ in range(100):
        fit = est.ols(A, F + rng.normal(scale=2.0, size=F.shape))
        z.append((fit.beta - truth) / fit.std)
    z = np.abs(np.array(z))
    # Gaussian force noise: |z| < 1 for 68.3 % and < 2 for 95.4 %; 100 repetitions of 79
    # correlated parameters leave a few percent of sampling error
    assert abs(np.mean(z < 1) - 0.683) < 0.04
    assert abs(np.mean(z < 2) - 0.954) < 0.02


def test_savitzky_golay_derivatives_of_a_smooth_motion(dasgupta):
    model = se.make_dynamics("improved", dasgupta)
    series = exc.random_excitation(dasgupta, model, np.random.default_rng(0), period=10.0)
    times = np.arange(0, 10.0, experiment.SAMPLE_DT)
    exact = exc.task_states(*series.sample(times))
    got = est.derivatives(experiment.SAMPLE_DT, exact[0], exact[1])
    inner = slice(est.SAVGOL_WINDOW, -est.SAVGOL_WINDOW)
    for g, e in zip(got, exact):
        # a cubic over 0.1 s of a series of 0.1-0.5 Hz (the command's default): the filter's bias, under 1 %
        assert np.abs(g[inner] - e[inner]).max() < 1e-2 * np.abs(e).max()


@pytest.mark.slow  # the constrained fit of 135 parameters to convergence: about a minute
def test_physically_consistent_estimate_has_real_bodies_and_fits_the_data(noise_free, dasgupta):
    model, base, A, record, truth = noise_free
    rng = np.random.default_rng(2)
    F = record.true_forces + rng.normal(scale=1.0, size=record.true_forces.shape)
    fit = est.wls(A, F)
    nominal = reg.theta_of(dasgupta, model.flags)
    theta = est.consistent(A, F, base, nominal, base.theta_from(fit.beta, nominal))
    params = base_mod.params_from_theta(theta, dasgupta, model.flags)  # raises unless every body is real
    for body in (params.platform, *params.upper_leg, *params.lower_leg):
        moments = np.linalg.eigvalsh(body.inertia)
        assert body.mass > 0 and moments.min() >= -1e-12
        # triangle inequalities of the principal moments, to rounding
        assert moments[0] + moments[1] >= moments[2] - 1e-9 * moments.max()
    res_wls = np.sqrt(np.mean((np.einsum("tir,r->ti", A, fit.beta) - F) ** 2))
    res_c = np.sqrt(np.mean((np.einsum("tir,r->ti", A, base.of_theta(theta)) - F) ** 2))
    # the constraints cost little fit on a plant whose truth is itself a real body: under 10 %
    assert res_c < 1.1 * res_wls


def test_bad_inputs_end_in_clear_errors(noise_free, dasgupta):
    model, base, A, record, truth = noise_free
    with pytest.raises(IdentificationError, match="rank-deficient"):
        est.check_rank(A[:, :, :1] * np.ones((1, 1, base.rank)), base)
    with pytest.raises(IdentificationError, match="equations"):
        est.check_rank(A[:5], base)
    with pytest.raises(IdentificationError, match="too short"):
        experiment.Settings(duration=1.0).check()
    with pytest.raises(IdentificationError, match="--noise-force"):
        experiment.Settings(noise_force=float("nan")).check()
    with pytest.raises(IdentificationError, match="--plant"):
        experiment.Settings(plant="newton").check()
    # a series far beyond the workspace: the legs leave their stroke
    big = exc.Excitation(
        np.concatenate([dasgupta.home_position, dasgupta.home_rpy]), np.zeros((6, 1)), np.zeros((6, 1)), 2.0
    )
    big = exc.Excitation(big.q0, big.a + np.array([[1.5], [0], [0], [0], [0], [0]]), big.b, 2.0)
    with pytest.raises(IdentificationError, match="stroke|diverged"):
        experiment.simulate(model, dasgupta, model, big, 3.0)
    with pytest.raises(IdentificationError, match="filter"):
        est.derivatives(0.01, np.zeros((5, 3)), np.broadcast_to(np.eye(3), (5, 3, 3)))


def run_cli(args, capsys):
    from stewart_env.cli import main

    code = main(["identify", *args])
    out = capsys.readouterr()
    return code, out.out, out.err


def test_identify_command_rejects_bad_settings_before_writing(tmp_path, capsys):
    out = tmp_path / "run"
    code, _, err = run_cli_exit(["--duration", "1", "--excitation", "random", "--out", str(out)], capsys)
    assert code == 2 and "argument --duration: expected a finite number in [1.5, 3600], got '1'" in err
    assert not out.exists() or not any(p.name != ".stewart-env.lock" for p in out.iterdir())
    code, _, err = run_cli(["--plant", "mujoco", "--derivatives", "exact", "--out", str(out)], capsys)
    # the setting's error carries its name: said of its flag, as argparse says its own
    assert code == 2 and err.startswith(
        "stewart-env identify: error: argument --derivatives: exact: the MuJoCo plant gives no accelerations"
    ), err


@pytest.mark.slow  # a 6 s simulation, two estimates and the constrained fit: about 20 s
def test_identify_command_writes_a_platform_other_commands_load(tmp_path, capsys):
    out = tmp_path / "run"
    code, text, err = run_cli(
        ["--excitation", "random", "--duration", "6", "--period", "3", "--noise-force", "0.5", "--out", str(out)],
        capsys,
    )
    assert code == 0, err
    assert "held-out leg-force RMS error" in text
    params = se.load_platform(str(out / "platform.yaml"))
    assert params.platform.mass > 0
    import json

    report = json.loads((out / "report.json").read_text())
    err = report["held_out_force_error"]
    # identified from noisy forces, it predicts the held-out forces far better than the nominal
    assert err["wls"] < 0.2 * err["nominal"] and err["consistent"] < 0.2 * err["nominal"]
    assert sorted(p.name for p in out.iterdir() if not p.name.startswith(".")) == [
        "platform.yaml",
        "report.json",
        "report.md",
        "truth.yaml",
    ]
    # per base parameter: its relative standard deviation and what brings it to 10 %, as requirements says
    rows = report["base_parameters"]
    need = est.requirements(
        np.array([p["wls"] for p in rows]), np.array([p["wls_std"] for p in rows]), report["fitted_duration"], 0.5
    )
    dropped = 6 - report["fitted_duration"]
    for p, rel, time, noise, zero in zip(rows, need.rel_std, need.duration, need.noise, need.near_zero):
        assert (p["rel_std"], p["duration_10pct"], p["noise_force_10pct"], p["near_zero"]) == (
            rel,
            time + dropped,
            noise,
            zero,
        )
    assert report["base_parameters_under_10pct_rel_std"] == int(np.sum(need.rel_std < 0.1))
    table = (out / "report.md").read_text()
    assert "| base parameter | WLS | std | rel. std | --duration for 10 %, s | force noise for 10 %, N |" in table
    assert table.count("| ~0 | ~0 |") == int(need.near_zero.sum()) > 0

    # a second, longer run: the first one's standard deviations, scaled by sqrt(T), predict its own
    again = tmp_path / "again"
    code, text, err = run_cli(
        [
            "--excitation",
            "random",
            "--duration",
            "9",
            "--period",
            "3",
            "--noise-force",
            "1",
            "--predicted-by",
            str(out / "report.json"),
            "--out",
            str(again),
        ],
        capsys,
    )
    assert code == 0, err
    prediction = json.loads((again / "report.json").read_text())["predicted_by"]
    assert prediction["fitted_duration"] == report["fitted_duration"] and prediction["noise_force"] == 0.5
    # the same series (the seed), records of 1.8 and 2.8 of its periods: A^T A grows about linearly
    assert 0.75 < prediction["std_ratio"]["median"] < 1.33
    assert "against what a run of" in text


def test_mujoco_plant_without_the_extra_is_named(monkeypatch):
    import stewart_env.mujoco.library as library

    monkeypatch.setattr(library, "_mj", None)
    with pytest.raises(IdentificationError, match="--plant mujoco: .*not installed"):
        experiment.Settings(plant="mujoco").check()


# -- the excitation's series, the measurement delay, the time and noise for 10 % --------------------


def test_the_series_is_evaluated_once_by_the_compiled_law(dasgupta):
    model = se.make_dynamics("improved", dasgupta)
    series = exc.random_excitation(dasgupta, model, np.random.default_rng(1), period=3.0)
    times = np.linspace(0.0, 6.0, 37)
    q, qd, qdd = series.sample(times)
    # the formula of the module docstring, written out: the same operations up to their order
    t = times[:, None, None]
    wk = series.wf * np.arange(1, series.harmonics + 1)
    s, c = np.sin(wk * t), np.cos(wk * t)
    want = (
        series.q0 + np.sum((series.a * s - series.b * c) / wk, axis=2),
        np.sum(series.a * c + series.b * s, axis=2),
        np.sum(wk * (series.b * c - series.a * s), axis=2),
    )
    for got, w in zip((q, qd, qdd), want):
        assert np.abs(got - w).max() <= 1e-14 * np.abs(w).max()  # five terms summed: rounding only
    # on the reference the law's feedback vanishes: its forces are the controller's inverse dynamics
    states = exc.task_states(q, qd, qdd)
    row = series.law_row(model)[None]
    from stewart_env.dynamics.rk4 import law_forces

    for k, time in enumerate(times):
        F = law_forces(
            exc.FOURIER_COMPUTED_TORQUE,
            row,
            *(np.ascontiguousarray(x[k : k + 1]) for x in states[:4]),
            time=float(time),
        )
        F_id = model.inverse(*(x[k] for x in states))
        # roll-pitch-yaw back from the rotation matrix and the rates through E: rounding, times cond ~ 10
        assert np.abs(F[0] - F_id).max() < 1e-9 * np.abs(F_id).max()
    with pytest.raises(ValueError, match="b"):
        exc.Excitation(series.q0, series.a, series.b[:, :2], series.wf).sample(times)


@pytest.fixture(scope="module")
def plant_run(dasgupta):
    """A short noise-free run of the plant along a random series: (plant, trajectory)."""
    model = se.make_dynamics("improved", dasgupta)
    series = exc.random_excitation(dasgupta, model, np.random.default_rng(4), period=3.0)
    return model, experiment.simulate(model, dasgupta, model, series, 3.0)


def test_no_delay_measures_as_before(plant_run):
    plant, traj = plant_run
    settings = experiment.Settings(noise_position=1e-5, noise_angle=1e-5, noise_force=1.0)
    record = experiment.measure(plant, traj, settings, np.random.default_rng(5))
    # the measurement without a delay, written out: the same draws in the same order
    rng, n = np.random.default_rng(5), traj.time.size
    pos = traj.position + rng.normal(scale=1e-5, size=(n, 3))
    rot = se.rotations.rotvec_to_matrix(rng.normal(scale=1e-5, size=(n, 3))) @ traj.rotation
    forces = traj.leg_forces + rng.normal(scale=1.0, size=(n, 6))
    keep = traj.time >= experiment.SETTLE
    keep[-(est.SAVGOL_WINDOW // 2 + 1) :] = False
    assert np.array_equal(record.time, traj.time[keep]) and np.array_equal(record.forces, forces[keep])
    for got, want in zip(record.states, est.derivatives(experiment.SAMPLE_DT, pos, rot)):
        assert np.array_equal(got, want[keep])


@pytest.mark.parametrize("derivatives", ["exact", "filter"])
def test_a_delay_shifts_the_poses_by_whole_samples(plant_run, derivatives):
    plant, traj = plant_run
    k = 4
    on_time = experiment.measure(plant, traj, experiment.Settings(derivatives=derivatives), np.random.default_rng(0))
    late = experiment.measure(
        plant,
        traj,
        experiment.Settings(derivatives=derivatives, delay=k * experiment.SAMPLE_DT),
        np.random.default_rng(0),
    )
    # the same samples kept, the forces of their own time, every motion quantity k samples old
    assert np.array_equal(late.time, on_time.time) and np.array_equal(late.forces, on_time.forces)
    if derivatives == "exact":
        index = np.searchsorted(traj.time, late.time)
        assert np.array_equal(late.states[0], traj.position[index - k])
    for got, want in zip(late.states, on_time.states):
        assert np.array_equal(got[k:], want[:-k])
        assert not np.array_equal(got[:k], want[:k])


def test_bad_delays_are_refused_naming_the_option(tmp_path, capsys):
    for delay, says in (
        (0.003, "expected a whole number of samples"),
        (-0.005, "expected seconds"),
        (float("nan"), "expected"),
        (float("inf"), "expected"),
        (experiment.MAX_DELAY + experiment.SAMPLE_DT, "expected seconds"),
    ):
        with pytest.raises(IdentificationError, match=f"^--delay: {says}"):
            experiment.Settings(delay=delay).check()
    experiment.Settings(delay=experiment.MAX_DELAY).check()
    assert experiment.Settings(delay=0.015).delay_samples == 3
    out = tmp_path / "run"
    for value in ("0.003", "-0.005", "nan", "1"):
        code, _, err = run_cli_exit(
            ["--excitation", "random", "--duration", "6", "--period", "3", "--delay", value, "--out", str(out)], capsys
        )
        # argparse's refusal (a negative or non-finite number) follows its usage; the command's own is one line
        assert code == 2 and "--delay" in err.strip().splitlines()[-1], err
        assert not out.exists() or not any(p.name != ".stewart-env.lock" for p in out.iterdir())


def run_cli_exit(args, capsys):
    """run_cli, with argparse's refusals (SystemExit) as their exit code."""
    try:
        return run_cli(args, capsys)
    except SystemExit as stop:
        out = capsys.readouterr()
        return stop.code, out.out, out.err


def test_requirements_follow_one_over_the_square_root_of_the_record():
    beta = np.array([10.0, -2.0, 0.5, 0.0, 1.0])
    std = np.array([0.5, 0.4, 0.3, 0.1, 0.0])
    need = est.requirements(beta, std, duration=60.0, noise=2.0)
    assert np.allclose(need.rel_std[:3], [0.05, 0.2, 0.6]) and need.rel_std[3] == np.inf and need.rel_std[4] == 0
    # RSD 0.05 reaches 10 % in a quarter of the record or at twice the noise; 0.2 in four times it or at half
    assert np.allclose(need.duration[:2], [15.0, 240.0]) and np.allclose(need.noise[:2], [4.0, 1.0])
    assert need.duration[3] == np.inf and need.noise[3] == 0.0
    assert need.near_zero.tolist() == [False, False, True, True, False]
    assert np.all(est.requirements(beta, std, 60.0, noise=0.0).noise == np.inf)


def test_standard_deviations_shrink_as_one_over_the_square_root_of_the_record(noise_free):
    model, base, A, record, truth = noise_free
    F = record.true_forces + np.random.default_rng(11).normal(scale=1.0, size=record.true_forces.shape)
    period = int(round(3.0 / experiment.SAMPLE_DT))  # the fixture's series repeats every 3 s
    one, whole = est.ols(A[:period], F[:period]), est.ols(A, F)
    # the record's rows at 60 % of their time: the law T (RSD / target)^2 predicts the whole record's std
    need = est.requirements(one.beta, one.std, 1.0, noise=1.0, target=1.0)
    predicted = one.std * np.sqrt(period / A.shape[0])
    assert np.allclose(need.duration, need.rel_std**2)
    ratio = whole.std / predicted
    # the 0.8 period beyond the first is not a whole one, so A^T A grows only about linearly
    assert 0.8 < np.median(ratio) < 1.25, np.median(ratio)


def test_predicted_std_scales_with_the_noise_and_one_over_the_root_of_the_record():
    std = np.array([1.0, 0.2])
    assert np.allclose(est.predicted_std(std, 60.0, 1.0, 240.0, 1.0), std / 2)
    assert np.allclose(est.predicted_std(std, 60.0, 1.0, 60.0, 5.0), std * 5)


def test_a_reference_report_that_does_not_fit_is_refused_before_any_work(tmp_path, capsys):
    import json

    bad = tmp_path / "bad.json"
    for document, says in (
        ({"platform": "dasgupta1998"}, "not a report.json"),
        (
            {
                "platform": "motion_simulator",
                "settings": {"model": "improved", "noise_force": 1.0},
                "fitted_duration": 5.0,
                "base_parameters": [{"name": "x", "wls": 1.0, "wls_std": 1.0}],
            },
            "a report of dasgupta1998's improved base parameters",
        ),
    ):
        bad.write_text(json.dumps(document))
        out = tmp_path / "run"
        code, _, err = run_cli(
            [
                "--excitation",
                "random",
                "--duration",
                "6",
                "--period",
                "3",
                "--predicted-by",
                str(bad),
                "--out",
                str(out),
            ],
            capsys,
        )
        assert code == 2 and err.startswith("stewart-env identify: error: --predicted-by: ") and says in err, err
        assert not out.exists() or not any(p.name != ".stewart-env.lock" for p in out.iterdir())
    bad.write_text("{")
    code, _, err = run_cli(["--predicted-by", str(bad), "--out", str(tmp_path / "run")], capsys)
    assert code == 2 and "--predicted-by" in err and "not valid JSON" in err
    code, _, err = run_cli(["--predicted-by", str(tmp_path / "none.json"), "--out", str(tmp_path / "run")], capsys)
    assert code == 2 and "--predicted-by" in err and "No such file" in err
    run = tmp_path / "run"
    assert not run.exists() or not any(p.name != ".stewart-env.lock" for p in run.iterdir())


def test_mujoco_records_the_force_around_each_stamp_not_the_one_held_after_it(dasgupta):
    """MuJoCo's plant holds the law's force from each 5 ms stamp to the next; the filtered
    accelerations are centred on the stamp, so the recorded force must be the mean of the forces
    held before and after it (read as the one held after, it leads the motion by half a period)."""
    pytest.importorskip("mujoco")
    from stewart_env.dynamics.rk4 import law_forces

    model = se.make_dynamics("improved", dasgupta)
    series = exc.random_excitation(dasgupta, model, np.random.default_rng(1), period=3.0)
    traj = experiment.simulate("mujoco", dasgupta, model, series, 0.1)
    row = series.law_row(model)[None]
    law = exc.FOURIER_COMPUTED_TORQUE
    applied = np.concatenate(
        [
            law_forces(law, row, *(x[k : k + 1] for x in traj[1:5]), time=float(traj.time[k]))
            for k in range(traj.time.size)
        ]
    )
    assert traj.time.size == 21 and np.abs(np.diff(applied, axis=0)).max() > 1.0  # the forces move between stamps
    assert np.array_equal(traj.leg_forces[1:], 0.5 * (applied[:-1] + applied[1:]))
    assert np.array_equal(traj.leg_forces[0], applied[0])
