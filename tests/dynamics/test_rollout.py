"""The one RK4 integrator: forces held, or given by a compiled control law at every stage."""

import ctypes

import numpy as np
import pytest

import stewart_env as se
from stewart_env.dynamics import rk4
from stewart_env.integrate import Trajectory, rollout_inplace

try:
    import numba
except ImportError:  # a user's laws as numba cfuncs need the optional extra "laws"
    numba = None
needs_numba = pytest.mark.skipif(numba is None, reason="numba (the extra 'laws') is not installed")

N_ROWS = 17  # a batch of many rows


def _law(body):
    """``body`` compiled as a numba cfunc control law (None without numba; its tests skip)."""
    return None if numba is None else rk4.ControlLaw(numba.cfunc(rk4.numba_law_signature(), cache=True)(body))


@pytest.fixture
def batch(dasgupta):
    """A batch of N_ROWS states near home, moving, with forces near the holding ones and a wrench."""
    rng = np.random.default_rng(7)
    t = np.tile(dasgupta.home_position, (N_ROWS, 1)) + rng.normal(scale=0.01, size=(N_ROWS, 3))
    R = np.stack([se.rpy_to_matrix(rng.normal(scale=0.05, size=3)) for _ in range(N_ROWS)])
    v = rng.normal(scale=0.1, size=(N_ROWS, 3))
    w = rng.normal(scale=0.1, size=(N_ROWS, 3))
    z = np.zeros((N_ROWS, 3))
    model = se.make_dynamics("improved", dasgupta)
    F = model.inverse(t, R, z, z, z, z) + rng.normal(scale=50, size=(N_ROWS, 6))
    W = rng.normal(scale=5, size=(N_ROWS, 6))
    return model, (t, R, v, w), F, W


#: Final [t, R (row-major), v, w] after 20 steps of 1 ms of the batch above on ``improved``, as the
#: rollout computed them before it gained control laws (its kernel then held the forces itself).
BEFORE_CONTROL_LAWS = [
    # row 0
    [
        0.0003713781220542542,
        0.006672712028904253,
        0.3956376191009799,
        0.9996428562093037,
        -0.026698682894232675,
        0.0011577397887891062,
        0.026575575949221768,
        0.9977221400818058,
        0.062002177006525,
        -0.0028104790823778206,
        -0.06194926571231107,
        0.9980753426896353,
        0.019514897559763163,
        0.14421907892201716,
        -0.07904854229053344,
        -0.2010502779767351,
        -0.06018034320603486,
        -0.19549291857176884,
    ],
    # row 16
    [
        -0.00787737606652591,
        0.018931076623587582,
        0.40669608083951636,
        0.998987775598808,
        0.04378843981052877,
        -0.010295471970999944,
        -0.0425538403691858,
        0.9941536888552128,
        0.09923514299585007,
        0.014580633524638037,
        -0.09869658289187452,
        0.9950107485105314,
        -0.07681449128672917,
        -0.07475720810033074,
        -0.036672973826899026,
        0.2072369036592213,
        0.0026679632212407147,
        0.16003315170468382,
    ],
    # row 3 alone
    [
        -0.004863903620884143,
        0.0029972046664817897,
        0.4031963162312784,
        0.9996472441472642,
        -0.008664153266063266,
        -0.0251061689025318,
        0.008353595047268219,
        0.9998876212286248,
        -0.012448387989965016,
        0.025211202243577074,
        0.012234269980044359,
        0.9996072818459704,
        0.08210725247976035,
        -0.08686427312938795,
        -0.029402252909733542,
        0.06925116337800488,
        -0.0589828129853196,
        0.22559559317367694,
    ],
]


def _flat(state):
    return np.concatenate([np.ravel(x) for x in state])


def test_held_forces_give_the_results_of_before_control_laws(batch):
    model, state, F, W = batch
    end = se.rollout(model, *state, F, dt=1e-3, steps=20, external_wrench=W)
    single = se.rollout(model, *(x[3] for x in state), F[3], dt=1e-3, steps=20, external_wrench=W[3])
    got = [_flat(x[0] for x in end), _flat(x[16] for x in end), _flat(single)]
    for g, e in zip(got, BEFORE_CONTROL_LAWS):
        # equal bit for bit when captured; the bound leaves room for the kernels' own rounding
        # (fused multiply-adds, inlining: 1e-15 per evaluation, 80 evaluations)
        np.testing.assert_allclose(g, e, rtol=0, atol=1e-13 * np.abs(e).max())


@_law
def _hold(time, position, rotation, velocity, angular_velocity, params, n_params, forces):
    for i in range(6):
        forces[i] = params[i]


@_law
def _swaying(time, position, rotation, velocity, angular_velocity, params, n_params, forces):
    """params[:6] plus params[6] sin(params[7] t) on every leg: a law that depends on time."""
    for i in range(6):
        forces[i] = params[i] + params[6] * np.sin(params[7] * time)


@needs_numba
def test_a_law_that_holds_the_forces_is_the_held_rollout_bit_for_bit(batch):
    model, state, F, W = batch
    held = se.rollout(model, *state, F, dt=1e-3, steps=20, external_wrench=W)
    for law in (_hold, rk4.CONSTANT_FORCES):
        by_law = se.rollout(model, *state, dt=1e-3, steps=20, external_wrench=W, control_law=law, control_params=F)
        for a, b in zip(held, by_law):
            np.testing.assert_array_equal(a, b)  # the same RK4 row: the law only supplies F


def test_rollout_inplace_is_rollout(batch):
    model, state, F, W = batch
    held = se.rollout(model, *state, F, dt=1e-3, steps=20, external_wrench=W)
    arrays = [x.copy() for x in state]
    rollout_inplace(model, *arrays, F, W, 1e-3, 20)
    for a, b in zip(held, arrays):
        np.testing.assert_array_equal(a, b)


@needs_numba
def test_per_row_parameters_equal_rows_run_alone(batch):
    model, state, F, W = batch
    params = np.hstack([F, np.linspace(0, 200, N_ROWS)[:, None], np.full((N_ROWS, 1), 30.0)])
    end = se.rollout(model, *state, dt=1e-3, steps=20, external_wrench=W, control_law=_swaying, control_params=params)
    for b in (0, 5, 16):
        alone = se.rollout(
            model,
            *(x[b] for x in state),
            dt=1e-3,
            steps=20,
            external_wrench=W[b],
            control_law=_swaying,
            control_params=params[b],
        )
        for a, x in zip(alone, end):
            np.testing.assert_array_equal(a, x[b])  # rows are independent: the batch changes nothing
    # one parameter row (P,) is shared by every platform of the batch
    shared = se.rollout(
        model, *state, dt=1e-3, steps=20, external_wrench=W, control_law=_swaying, control_params=params[5]
    )
    tiled = se.rollout(
        model,
        *state,
        dt=1e-3,
        steps=20,
        external_wrench=W,
        control_law=_swaying,
        control_params=np.tile(params[5], (N_ROWS, 1)),
    )
    for a, b in zip(shared, tiled):
        np.testing.assert_array_equal(a, b)


@needs_numba
def test_a_time_dependent_law_converges_at_fourth_order(dasgupta):
    """The law sees each stage's own time; were it given the step's start, RK4 would drop to first order."""
    model = se.make_dynamics("improved", dasgupta)
    R = se.rpy_to_matrix(dasgupta.home_rpy)
    zero = np.zeros(3)
    hold = model.inverse(dasgupta.home_position, R, zero, zero, zero, zero)
    params = np.concatenate([hold, [300.0, 40.0]])

    def run(dt):
        return se.rollout(
            model,
            dasgupta.home_position,
            R,
            zero,
            zero,
            dt=dt,
            steps=round(0.2 / dt),
            control_law=_swaying,
            control_params=params,
        )[0]

    reference = run(1e-4)
    errors = [np.abs(run(dt) - reference).max() for dt in (4e-3, 2e-3)]
    # halving dt divides a fourth-order error by 16; 10 leaves room for the higher-order terms
    assert errors[0] / errors[1] > 10
    assert errors[1] < 1e-8  # observed 2.7e-9 m at dt = 2 ms
    assert np.abs(reference - dasgupta.home_position).max() > 1e-2  # the sway does move it: 9 cm


@needs_numba
def test_start_time_continues_a_run(dasgupta):
    model = se.make_dynamics("improved", dasgupta)
    R = se.rpy_to_matrix(dasgupta.home_rpy)
    zero = np.zeros(3)
    hold = model.inverse(dasgupta.home_position, R, zero, zero, zero, zero)
    kw = dict(dt=1e-3, control_law=_swaying, control_params=np.concatenate([hold, [300.0, 40.0]]))
    whole = se.rollout(model, dasgupta.home_position, R, zero, zero, steps=40, **kw)
    half = se.rollout(model, dasgupta.home_position, R, zero, zero, steps=20, **kw)
    rest = se.rollout(model, *half, steps=20, start_time=0.02, **kw)
    for a, b in zip(whole, rest):
        # the restart goes through the rotation matrix and back to a quaternion: rounding only
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-14)


@needs_numba
def test_recorded_trajectory(batch):
    model, state, F, W = batch
    params = np.hstack([F, np.full((N_ROWS, 1), 100.0), np.full((N_ROWS, 1), 30.0)])
    kw = dict(dt=1e-3, steps=20, external_wrench=W, control_law=_swaying, control_params=params)
    end = se.rollout(model, *state, **kw)
    run = se.rollout(model, *state, record_every=5, **kw)
    assert isinstance(run, Trajectory)
    # below an ulp of every nonzero sample (8.7e-19 at 0.005): start_time + dt * every * k gives the literals' doubles
    np.testing.assert_allclose(run.time, [0.0, 0.005, 0.01, 0.015, 0.02], rtol=0, atol=1e-18)
    assert run.position.shape == (N_ROWS, 5, 3) and run.rotation.shape == (N_ROWS, 5, 3, 3)
    assert run.leg_forces.shape == (N_ROWS, 5, 6)
    for a, x in zip(state, run[1:5]):
        # the start, once through the quaternion the integrator carries: rounding only
        np.testing.assert_allclose(x[:, 0], a, rtol=0, atol=1e-15)
    for a, x in zip(end, run[1:5]):
        np.testing.assert_array_equal(x[:, -1], a)  # the end is the unrecorded run's end
    # the recorded forces are the law's at each sample; the compiled sin may differ from numpy's by
    # an ulp, times 100 N, on forces near 200 N: far below 1e-12
    expected = F[:, None, :] + 100.0 * np.sin(30.0 * run.time)[None, :, None]
    np.testing.assert_allclose(run.leg_forces, expected, rtol=1e-15, atol=1e-12)
    # one platform: no batch dimension
    one = se.rollout(
        model, *(x[2] for x in state), dt=1e-3, steps=20, external_wrench=W[2], record_every=10, leg_forces=F[2]
    )
    assert one.position.shape == (3, 3) and one.leg_forces.shape == (3, 6)
    np.testing.assert_array_equal(one.leg_forces, np.tile(F[2], (3, 1)))


@_law
def _explode(time, position, rotation, velocity, angular_velocity, params, n_params, forces):
    for i in range(6):
        forces[i] = params[0]


@needs_numba
def test_rows_that_diverge_are_named_or_returned(batch):
    model, state, F, W = batch
    params = np.zeros((N_ROWS, 1))
    params[[2, 9], 0] = 1e300  # forces that overflow the accelerations
    kw = dict(dt=1e-3, steps=10, external_wrench=W, control_law=_explode, control_params=params)
    with pytest.raises(FloatingPointError, match=r"batch rows \[2, 9\]"):
        se.rollout(model, *state, **kw)
    run = se.rollout(model, *state, check_finite=False, record_every=2, **kw)
    bad = ~np.isfinite(run.position).all(axis=(1, 2))
    assert bad.tolist() == [b in (2, 9) for b in range(N_ROWS)]
    assert not np.isfinite(run.position[[2, 9], -1]).any()  # a dead row stays dead to its last sample
    assert np.isfinite(run.position[0]).all()


def _not_a_law(time, position, rotation, velocity, angular_velocity, params, forces):
    forces[:] = 0.0


def _two_arguments(time, forces):
    forces[0] = 0.0


@needs_numba
def test_bad_arguments_are_named(batch):
    model, state, F, W = batch
    one = [x[0] for x in state]
    with pytest.raises(ValueError, match="^control_law: expected a compiled control law"):
        se.rollout(model, *one, control_law=_not_a_law, steps=1)
    with pytest.raises(ValueError, match="^control_law: expected a compiled control law"):
        se.rollout(model, *one, control_law=numba.njit(_not_a_law), steps=1)  # a jitted function is no C function
    two = numba.cfunc("void(float64, CPointer(float64))")(_two_arguments)
    with pytest.raises(ValueError, match="^control_law: _two_arguments does not have the signature of a control law"):
        se.rollout(model, *one, control_law=two, steps=1)
    with pytest.raises(ValueError, match="^leg_forces: the control_law gives"):
        se.rollout(model, *one, F[0], control_law=_hold, control_params=F[0], steps=1)
    with pytest.raises(ValueError, match="^leg_forces: required"):
        se.rollout(model, *one, steps=1)
    with pytest.raises(ValueError, match="^control_params: given without"):
        se.rollout(model, *one, F[0], control_params=F[0], steps=1)
    with pytest.raises(ValueError, match="^control_params: contains NaN"):
        se.rollout(model, *one, control_law=_hold, control_params=np.full(6, np.nan), steps=1)
    with pytest.raises(ValueError, match="^control_params: expected an array"):
        se.rollout(model, *one, control_law=_hold, control_params=1.0, steps=1)
    with pytest.raises(ValueError, match="batch sizes disagree"):
        se.rollout(model, *state, control_law=_hold, control_params=F[:3], steps=1)
    with pytest.raises(ValueError, match="^record_every: must be a positive integer dividing steps = 10"):
        se.rollout(model, *one, F[0], steps=10, record_every=3)
    with pytest.raises(ValueError, match="^start_time"):
        se.rollout(model, *one, F[0], steps=1, start_time=np.inf)


def test_a_half_turn_is_carried_exactly(dasgupta):
    """The integrator's quaternion comes from Shepperd's method, exact at a half turn (w = 0)."""
    model = se.make_dynamics("improved", dasgupta)
    zero = np.zeros(3)
    for R in (np.diag([-1.0, -1.0, 1.0]), np.diag([1.0, -1.0, -1.0]), np.diag([-1.0, 1.0, -1.0])):
        run = se.rollout(model, dasgupta.home_position, R, zero, zero, np.zeros(6), steps=0, record_every=1)
        np.testing.assert_array_equal(run.rotation[0], R)  # a half turn's quaternion is exact: no rounding
        # and the rotation stays a rotation under motion (forces zero: the platform falls a little)
        end = se.rollout(model, dasgupta.home_position, R, zero, [0.0, 0.0, 0.5], np.zeros(6), steps=5)
        np.testing.assert_allclose(end[1].T @ end[1], np.eye(3), rtol=0, atol=1e-15)  # orthonormal to rounding


@needs_numba
def test_a_law_on_a_model_with_a_parameter_set_per_row(dasgupta):
    """Domain randomisation: one state and one law row for every platform, a parameter set per row."""
    d = dasgupta.to_dict()
    d["platform"]["mass"] = 60.0
    heavy = se.PlatformParams.from_dict(d)
    model = se.make_dynamics("improved", [dasgupta, heavy])
    R = se.rpy_to_matrix(dasgupta.home_rpy)
    zero = np.zeros(3)
    params = np.concatenate([np.full(6, -300.0), [50.0, 20.0]])
    end = se.rollout(
        model, dasgupta.home_position, R, zero, zero, steps=20, control_law=_swaying, control_params=params
    )
    for row, platform in enumerate((dasgupta, heavy)):
        alone = se.rollout(
            se.make_dynamics("improved", platform),
            dasgupta.home_position,
            R,
            zero,
            zero,
            steps=20,
            control_law=_swaying,
            control_params=params,
        )
        for a, x in zip(alone, end):
            np.testing.assert_array_equal(a, x[row])  # row by row the same arithmetic
    assert not np.allclose(end[0][0], end[0][1])  # and the heavier platform moves differently


@_law
def _five_forces(time, position, rotation, velocity, angular_velocity, params, n_params, forces):
    for i in range(5):
        forces[i] = params[i]


@needs_numba
def test_a_law_that_leaves_a_force_unwritten_stops_the_rollout(batch):
    """The sixth force is NaN, not whatever the buffer held: the rollout names the rows."""
    model, state, F, W = batch
    one = [x[0] for x in state]
    with pytest.raises(FloatingPointError, match=r"rows \[0\].*left a leg force unwritten"):
        se.rollout(model, *one, control_law=_five_forces, control_params=F[0], steps=2)
    run = se.rollout(
        model, *one, control_law=_five_forces, control_params=F[0], steps=2, record_every=1, check_finite=False
    )
    assert np.isnan(run.leg_forces[1, 5]) and np.isfinite(run.leg_forces[1, :5]).all()


@pytest.mark.parametrize(
    "name,value",
    [
        ("steps", 2**63),
        ("steps", 10**30),
        ("steps", np.inf),
        ("steps", np.nan),
        ("steps", 1.5),
        ("steps", True),
        ("dt", "1e-3"),
        ("dt", None),
        ("dt", np.ones(2)),
        ("dt", 0.0),
        ("dt", np.nan),
        ("start_time", "0"),
        ("start_time", None),
        ("start_time", np.ones(2)),
        ("record_every", np.nan),
        ("record_every", 0),
        ("record_every", 2.5),
    ],
)
def test_step_arguments_are_named(batch, name, value):
    """dt, steps, start_time and record_every are refused by name, never run (2**63 steps used to
    return the start unchanged) nor failing inside numba."""
    model, state, F, W = batch
    kwargs = {"dt": 1e-3, "steps": 2, name: value}
    with pytest.raises(ValueError, match=f"^{name}: "):
        se.rollout(model, *[x[0] for x in state], F[0], **kwargs)


def test_a_recording_too_large_to_hold_names_record_every(batch):
    model, state, F, W = batch
    with pytest.raises(ValueError, match="^record_every: .* GiB"):
        se.rollout(model, *[x[0] for x in state], F[0], steps=10**12, record_every=1)


def test_a_law_failing_on_its_parameters_names_control_law(batch, dasgupta):
    """The PD law with a parameter row of the wrong length: the error names the law and the shape."""
    from stewart_env.agents import pd_control_law

    model, state, F, W = batch
    with pytest.raises(ValueError, match=r"^control_law: pd_control_law failed on control_params of shape \(1, 5\)"):
        se.rollout(model, *[x[0] for x in state], control_law=pd_control_law, control_params=np.ones(5), steps=1)


def test_a_ctypes_function_is_a_control_law(batch):
    """A law reaches the integrator as a C function pointer: here a Python function behind ctypes,
    called with the GIL taken back; it gives the held forces' rollout bit for bit."""
    model, state, F, W = batch
    one = [x[0] for x in state]
    seen = []

    def hold(time, position, rotation, velocity, angular_velocity, params, n_params, forces):
        seen.append(n_params)
        for i in range(6):
            forces[i] = params[i]

    law = rk4.ControlLaw(rk4.LAW_CTYPES(hold), name="hold")
    by_law = se.rollout(model, *one, dt=1e-3, steps=3, external_wrench=W[0], control_law=law, control_params=F[0])
    held = se.rollout(model, *one, F[0], dt=1e-3, steps=3, external_wrench=W[0])
    for a, b in zip(held, by_law):
        np.testing.assert_array_equal(a, b)
    assert seen == [6] * 12  # four stages of three steps, each given the row's length
    untyped = ctypes.CFUNCTYPE(None, ctypes.c_double)(lambda time: None)
    with pytest.raises(ValueError, match="^control_law: .* does not have the signature of a control law"):
        se.rollout(model, *one, control_law=untyped, steps=1)


def test_a_law_declaring_its_row_length_refuses_other_rows(batch):
    model, state, F, W = batch
    law = rk4.ControlLaw(rk4.LAW_CTYPES(lambda *args: None), n_params=8, name="eight")
    with pytest.raises(
        ValueError,
        match=r"^control_law: eight failed on control_params of shape \(1, 6\): it reads "
        r"rows of 8 numbers",
    ):
        se.rollout(model, *[x[0] for x in state], control_law=law, control_params=F[0], steps=1)
    with pytest.raises(ValueError, match="^n_params: "):
        rk4.ControlLaw(rk4.LAW_CTYPES(lambda *args: None), n_params=-1)


# -- rollout with a control law: what is not a compiled law, bad parameters --------------------


def _wrong_signature(time, position):
    pass


def _jitted(time, position, rotation, velocity, angular_velocity, params, forces):
    forces[0] = 0.0


def _returns_a_value(time, position, rotation, velocity, angular_velocity, params, n_params, forces):
    return 1.0


def _nan_forces(time, position, rotation, velocity, angular_velocity, params, n_params, forces):
    for i in range(6):
        forces[i] = np.nan


def _python_law(time, position, rotation, velocity, angular_velocity, params, forces):
    forces[:] = 0.0


#: What is not a compiled control law: plain Python, and (with numba) an njit function and cfuncs of
#: the wrong signature.
NOT_LAWS = {"python": _python_law, "lambda": lambda *a: None}
if numba is not None:
    NOT_LAWS.update(
        {
            "njit": numba.njit(_jitted),
            "wrong-signature": numba.cfunc("void(float64, CPointer(float64))")(_wrong_signature),
            "returns-a-value": numba.cfunc(
                "float64(float64, CPointer(float64), CPointer(float64), CPointer(float64), "
                "CPointer(float64), CPointer(float64), int64, CPointer(float64))"
            )(_returns_a_value),
        }
    )


@pytest.mark.parametrize("law", list(NOT_LAWS.values()), ids=list(NOT_LAWS))
def test_rollout_refuses_a_law_that_is_not_a_compiled_law_naming_control_law(model, home, law):
    t, R, z = home
    with pytest.raises(ValueError, match=r"^control_law: "):
        se.rollout(model, t, R, z, z, steps=10, control_law=law)


@needs_numba
def test_rollout_law_giving_nan_forces_raises_naming_the_rows(model, home):
    t, R, z = home
    nan_forces = numba.cfunc(se.dynamics.rk4.numba_law_signature())(_nan_forces)
    with pytest.raises(FloatingPointError, match=r"non-finite in batch rows \[0\]"):
        se.rollout(model, t, R, z, z, steps=10, control_law=nan_forces)
    final = se.rollout(model, t, R, z, z, steps=10, control_law=nan_forces, check_finite=False)[0]
    assert np.isnan(final).all()  # unchecked, the rows come back NaN for the caller to see


@pytest.fixture(scope="module")
def pd_row(dasgupta, model):
    from stewart_env.agents.controllers.pd import pd_control_params

    ws = model.workspace(1)
    z = np.zeros(3)
    return pd_control_params(dasgupta, se.Reference(ws.position[0].copy(), ws.rotation[0].copy(), z, z))


@pytest.mark.parametrize(
    "params, message",
    [
        ("nan", r"^control_params: contains NaN or inf"),
        ("3d", r"^control_params: expected an array \(P,\) or \(N, P\)"),
        ("str", r"^control_params: "),
    ],
)
def test_rollout_refuses_bad_control_params_naming_them(model, home, pd_row, params, message):
    from stewart_env.agents.controllers.pd import pd_control_law

    t, R, z = home
    value = {"nan": np.full_like(pd_row, np.nan), "3d": pd_row[None, None], "str": "abc"}[params]
    with pytest.raises(ValueError, match=message):
        se.rollout(model, t, R, z, z, steps=10, control_law=pd_control_law, control_params=value)


def test_rollout_takes_leg_forces_or_a_law_not_both(model, home, pd_row):
    from stewart_env.agents.controllers.pd import pd_control_law

    t, R, z = home
    with pytest.raises(ValueError, match=r"^leg_forces: "):
        se.rollout(model, t, R, z, z, np.zeros(6), steps=10, control_law=pd_control_law, control_params=pd_row)
    with pytest.raises(ValueError, match=r"^control_params: given without a control_law"):
        se.rollout(model, t, R, z, z, np.zeros(6), steps=10, control_params=pd_row)


@pytest.mark.parametrize("every", [0, -1, 3, 2.5, "2", 10**30])
def test_rollout_refuses_a_record_every_that_does_not_divide_steps(model, home, every):
    t, R, z = home
    with pytest.raises(ValueError, match=r"^record_every: "):
        se.rollout(model, t, R, z, z, np.zeros(6), steps=100, record_every=every)


def test_rollout_records_the_pd_law_every_tenth_step(model, home, pd_row):
    from stewart_env.agents.controllers.pd import pd_control_law

    t, R, z = home
    trajectory = se.rollout(
        model, t, R, z, z, dt=1e-3, steps=100, control_law=pd_control_law, control_params=pd_row, record_every=10
    )
    assert trajectory.time.shape == (11,) and trajectory.position.shape == (11, 3)
    assert trajectory.leg_forces.shape == (11, 6)
    np.testing.assert_allclose(trajectory.time[[0, 1, -1]], [0.0, 0.01, 0.1], rtol=0, atol=1e-15)  # 10 * 1e-3 sums
    np.testing.assert_array_equal(trajectory.position[0], t)  # the start is recorded as given
    # the PD law held at home keeps the platform within 0.2 mm over 0.1 s (it sags ~0.12 mm under gravity)
    assert np.abs(trajectory.position - t).max() < 2e-4
    assert np.isfinite(trajectory.leg_forces).all()


@pytest.mark.parametrize("dt", [0, -1e-3, np.inf, np.nan])
def test_rollout_refuses_a_bad_dt(model, home, dt):
    t, R, z = home
    with pytest.raises(ValueError, match=r"^dt: "):
        se.rollout(model, t, R, z, z, np.zeros(6), dt=dt, steps=1)


def test_a_row_spread_once_per_rollout_is_the_row_in_the_lanes(dasgupta):
    """Nine rows with their own parameter sets: eight go through the lanes, the ninth alone (its
    row spread into leg lanes once for the rollout); each equals its platform's rollout alone, bit
    for bit, and a row never reads another's parameters."""
    platforms = []
    for k in range(9):
        d = dasgupta.to_dict()
        d["platform"]["mass"] = 30.0 + 5.0 * k
        platforms.append(se.PlatformParams.from_dict(d))
    model = se.make_dynamics("improved", platforms)
    R = se.rpy_to_matrix(dasgupta.home_rpy)
    zero = np.zeros((9, 3))
    t = np.tile(dasgupta.home_position, (9, 1))
    Rs = np.tile(R, (9, 1, 1))
    F = np.full((9, 6), -300.0)
    end = se.rollout(model, t, Rs, zero, zero, F, dt=1e-3, steps=10)
    for row in (0, 7, 8):
        alone = se.rollout(
            se.make_dynamics("improved", platforms[row]), t[row], R, zero[row], zero[row], F[row], dt=1e-3, steps=10
        )
        for a, x in zip(alone, end):
            np.testing.assert_array_equal(a, x[row])  # the same arithmetic in a lane and alone
    assert len({end[0][row, 2] for row in range(9)}) == 9  # each mass moves its platform differently
