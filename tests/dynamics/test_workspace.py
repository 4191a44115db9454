"""The workspace: a model's preallocated data.  Its calls give the checked API's results bit for
bit, allocate no Python objects per call, and its construction refuses what it cannot run, naming the argument."""

import copy
import pickle
import tracemalloc

import numpy as np
import pytest

import stewart_env as se
from stewart_env.dynamics.workspace import Workspace

from physics_reference import random_state

pytestmark = pytest.mark.physics


def random_batch(params, rng, n):
    states = [random_state(params, rng, speed=0.5) for _ in range(n)]
    t, R, v, w = (np.stack(x) for x in zip(*states))
    F = rng.normal(size=(n, 6)) * 300 + 180
    W = np.concatenate([rng.normal(scale=50.0, size=(n, 3)), rng.normal(scale=5.0, size=(n, 3))], axis=1)
    return t, R, v, w, F, W


@pytest.mark.parametrize("name", ["improved", "improved_centroidal", "classical"])
@pytest.mark.parametrize("n", [1, 3, 40])
def test_workspace_calls_equal_the_checked_calls_bit_for_bit(dasgupta, rng, name, n):
    model = se.make_dynamics(name, dasgupta)
    t, R, v, w, F, W = random_batch(dasgupta, rng, n)
    ws = model.workspace(n)
    ws.set_state(t, R, v, w)
    ws.leg_forces[:] = F
    ws.external_wrench[:] = W
    lin, ang = model.forward(t, R, v, w, F, W)
    assert np.array_equal(ws.forward(), np.hstack([lin, ang]))
    acc = rng.normal(size=(n, 6))
    ws.acceleration[:] = acc
    assert np.array_equal(ws.inverse(), model.inverse(t, R, v, w, acc[:, :3], acc[:, 3:], W))
    M, h = model.mass_and_bias(t, R, v, w, W)
    Mw, hw = ws.mass_and_bias()
    assert np.array_equal(Mw, M) and np.array_equal(hw, h)
    ws.leg_forces[:] = F
    ws.step(1e-3, steps=3)
    for got, want in zip(
        (ws.position, ws.rotation, ws.velocity, ws.angular_velocity),
        se.rollout(model, t, R, v, w, F, dt=1e-3, steps=3, external_wrench=W),
    ):
        assert np.array_equal(got, want)


def test_one_platform_workspace_equals_the_unbatched_call(dasgupta, rng):
    model = se.make_dynamics("improved", dasgupta)
    t, R, v, w = random_state(dasgupta, rng)
    F = rng.normal(size=6) * 300
    ws = model.workspace()
    ws.position[0], ws.rotation[0], ws.velocity[0], ws.angular_velocity[0] = t, R, v, w
    ws.leg_forces[0] = F
    assert ws.n == 1 and ws.model is model
    assert np.array_equal(ws.forward()[0], np.concatenate(model.forward(t, R, v, w, F)))


def test_workspace_starts_at_home_at_rest(dasgupta):
    ws = Workspace(se.make_dynamics("improved", dasgupta), 2)
    assert np.array_equal(ws.position, np.stack([dasgupta.home_position] * 2))
    assert np.array_equal(ws.rotation[1], se.rpy_to_matrix(dasgupta.home_rpy))
    assert not ws.velocity.any() and not ws.leg_forces.any() and not ws.external_wrench.any()
    ws.check()


def test_workspace_calls_allocate_no_python_objects(dasgupta):
    ws = se.make_dynamics("improved", dasgupta).workspace(1)
    calls = (ws.forward, ws.inverse, ws.mass_and_bias, lambda: ws.step(1e-3))
    for call in calls:
        call()  # compile and warm every path before measuring
    tracemalloc.start()
    try:
        before = tracemalloc.take_snapshot()
        for _ in range(1000):
            for call in calls:
                call()
        after = tracemalloc.take_snapshot()
    finally:
        tracemalloc.stop()
    grown = sum(s.size_diff for s in after.compare_to(before, "filename") if s.size_diff > 0)
    # 4000 calls: any allocation kept per call would show as kilobytes; the snapshots themselves
    # and the loop's frame objects account for a few hundred bytes
    assert grown < 2000


def test_workspace_arrays_are_preallocated_and_cannot_be_rebound(dasgupta):
    ws = se.make_dynamics("improved", dasgupta).workspace(4)
    for name, shape in [
        ("position", (4, 3)),
        ("rotation", (4, 3, 3)),
        ("velocity", (4, 3)),
        ("angular_velocity", (4, 3)),
        ("leg_forces", (4, 6)),
        ("external_wrench", (4, 6)),
        ("acceleration", (4, 6)),
        ("mass_matrix", (4, 6, 6)),
        ("bias", (4, 6)),
    ]:
        a = getattr(ws, name)
        assert a.shape == shape and a.dtype == np.float64 and a.flags.c_contiguous
        with pytest.raises(AttributeError):
            setattr(ws, name, np.zeros(shape))
    assert ws.forward() is ws.acceleration
    assert ws.inverse() is ws.leg_forces


@pytest.mark.parametrize(
    "model, n, message",
    [
        ("improved", 1, "model: expected a Dynamics"),
        (None, 0, "n: expected a positive integer"),
        (None, True, "n: expected a positive integer"),
        (None, 2.0, "n: expected a positive integer"),
    ],
)
def test_workspace_construction_names_the_argument(dasgupta, model, n, message):
    with pytest.raises(ValueError, match=message):
        Workspace(se.make_dynamics("improved", dasgupta) if model is None else model, n)


def test_workspace_batch_must_match_the_parameter_rows(dasgupta):
    model = se.make_dynamics("improved", [dasgupta] * 3)
    assert model.workspace(3).n == 3
    with pytest.raises(ValueError, match=r"n: the model has 3 parameter rows, so the workspace needs n = 3, got 2"):
        model.workspace(2)


def test_set_state_and_check_apply_the_entry_points_checks(dasgupta):
    ws = se.make_dynamics("improved", dasgupta).workspace(2)
    t, R = dasgupta.home_position, np.eye(3)
    with pytest.raises(ValueError, match="rotation: not a rotation matrix"):
        ws.set_state(t, 2 * R, np.zeros(3), np.zeros(3))
    with pytest.raises(ValueError, match="velocity: contains NaN or inf"):
        ws.set_state(t, R, [0.0, np.nan, 0.0], np.zeros(3))
    with pytest.raises(ValueError, match=r"batch sizes disagree"):
        ws.set_state(np.zeros((3, 3)), R, np.zeros(3), np.zeros(3))
    ws.set_state(t, R, np.zeros(3), np.zeros(3))
    ws.check()
    ws.leg_forces[1, 2] = np.inf
    with pytest.raises(ValueError, match="leg_forces: contains NaN or inf"):
        ws.check()
    ws.leg_forces[1, 2] = 0.0
    ws.rotation[0] *= 1.01
    with pytest.raises(ValueError, match=r"rotation: not a rotation matrix in batch rows \[0\]"):
        ws.check()


@pytest.mark.parametrize(
    "dt, steps, message",
    [
        (0.0, 1, "dt:"),
        (np.nan, 1, "dt:"),
        (np.inf, 1, "dt:"),
        ("0.001", 1, "dt:"),
        (None, 1, "dt:"),
        (np.array([1e-3, 1e-3]), 1, "dt:"),
        (1e-3, -1, "steps:"),
        (1e-3, 1.5, "steps:"),
        (1e-3, np.nan, "steps:"),
        (1e-3, np.inf, "steps:"),
        (1e-3, "3", "steps:"),
        (1e-3, 10**30, "steps:"),
        (1e-3, True, "steps:"),
    ],
)
def test_step_refuses_a_bad_step(dasgupta, dt, steps, message):
    ws = se.make_dynamics("improved", dasgupta).workspace()
    with pytest.raises(ValueError, match=message):
        ws.step(dt, steps)


def test_step_takes_numpy_scalars(dasgupta):
    ws = se.make_dynamics("improved", dasgupta).workspace()
    ws.step(np.float64(1e-3), np.int64(2))
    ws.check()


@pytest.mark.parametrize("n", [10**30, 2**63, 10**12])
def test_a_workspace_too_large_to_allocate_is_refused_naming_n(dasgupta, n):
    with pytest.raises(ValueError, match=f"n: a workspace of {n} platforms needs .* GiB"):
        se.make_dynamics("improved", dasgupta).workspace(n)


def test_set_state_refuses_a_batch_for_a_workspace_of_one_platform(dasgupta):
    ws = se.make_dynamics("improved", dasgupta).workspace(1)
    with pytest.raises(ValueError, match=r"position: expected shape \(3,\) or \(1, ...\) for this workspace of n = 1"):
        ws.set_state(np.zeros((2, 3)), np.eye(3), np.zeros(3), np.zeros(3))


def test_complex_arguments_are_refused_naming_the_argument(dasgupta):
    model = se.make_dynamics("improved", dasgupta)
    t = dasgupta.home_position.astype(complex)
    message = r"position: expected an array of numbers of shape \(3,\), got an array of complex128"
    with pytest.raises(ValueError, match=message):
        model.workspace().set_state(t, np.eye(3), np.zeros(3), np.zeros(3))
    with pytest.raises(ValueError, match=message):
        model.forward(t, np.eye(3), np.zeros(3), np.zeros(3), np.zeros(6))
    with pytest.raises(
        ValueError, match="position: expected an array of numbers of shape \\(3,\\), got an array of <U3"
    ):
        model.forward(np.array(["0.1", "0", "0.4"]), np.eye(3), np.zeros(3), np.zeros(3), np.zeros(6))


# -- the Workspace as an outside user meets it: bad arguments named, copies independent --------


@pytest.mark.parametrize("n", [0, -1, True, 1.0, 2.5, "2", None, np.float64(2.0)])
def test_workspace_refuses_a_batch_size_that_is_not_a_positive_integer(model, n):
    with pytest.raises(ValueError, match=r"^n: "):
        model.workspace(n)


@pytest.mark.parametrize("n", [10**9, 2**62, 2**63, 10**30])
def test_workspace_too_large_to_allocate_is_refused_naming_n(model, n):
    with pytest.raises(ValueError, match=r"^n: a workspace of \d+ platforms needs .* GiB"):
        model.workspace(n)


def test_workspace_set_state_refuses_a_batch_of_another_size(model, home):
    _, R, z = home
    with pytest.raises(ValueError, match=r"^position: .*n = 1, got a batch of 2"):
        model.workspace(1).set_state(np.zeros((2, 3)), R, z, z)


def test_workspace_set_state_refuses_complex_numbers(model, home):
    t, R, z = home
    with pytest.raises(ValueError, match=r"^position: .*complex"):
        model.workspace(1).set_state(t.astype(complex), R, z, z)


def test_workspace_n_must_match_the_models_parameter_rows(model, dasgupta):
    two_rows = model.with_params([dasgupta, dasgupta])
    with pytest.raises(ValueError, match=r"^n: the model has 2 parameter rows"):
        two_rows.workspace(3)


@pytest.mark.parametrize(
    "argument, value, message",
    [
        ("position", [np.nan, 0.0, 0.4], r"^position: contains NaN or inf"),
        ("velocity", [np.inf, 0.0, 0.0], r"^velocity: contains NaN or inf"),
        ("rotation", 2 * np.eye(3), r"^rotation: not a rotation matrix"),
        ("rotation", -np.eye(3), r"^rotation: not a rotation matrix"),
        ("position", np.zeros(4), r"^position: expected shape \(3,\)"),
        ("position", "abc", r"^position: expected an array of numbers"),
    ],
)
def test_workspace_set_state_refuses_naming_the_argument(model, home, argument, value, message):
    t, R, z = home
    ws = model.workspace(1)
    state = {**dict(position=t, rotation=R, velocity=z, angular_velocity=z), argument: value}
    before = ws.position.copy()
    with pytest.raises(ValueError, match=message):
        ws.set_state(**state)
    np.testing.assert_array_equal(ws.position, before)  # a refused state leaves the arrays as they were


def test_workspace_set_state_takes_float32_and_integer_arrays(model, home):
    _, R, z = home
    ws = model.workspace(1)
    ws.set_state(np.array([0, 0, 1]), np.eye(3, dtype=int), np.zeros(3, int), z.astype(np.float32))
    assert ws.position.dtype == np.float64
    np.testing.assert_array_equal(ws.position, [[0.0, 0.0, 1.0]])
    ws.set_state(np.array([0.0, 0.0, 0.4], np.float32), R.astype(np.float32), z, z)
    np.testing.assert_array_equal(ws.position, [[0.0, 0.0, np.float32(0.4)]])


def test_workspace_check_finds_what_was_written_in_place(model):
    ws = model.workspace(1)
    ws.position[0, 0] = np.nan
    with pytest.raises(ValueError, match=r"^position: contains NaN"):
        ws.check()
    ws.position[0, 0] = 0.0
    ws.rotation[0] = 2 * np.eye(3)
    with pytest.raises(ValueError, match=r"^rotation: not a rotation matrix"):
        ws.check()


def test_workspace_arrays_cannot_be_rebound(model):
    ws = model.workspace(1)
    with pytest.raises(AttributeError):
        ws.position = np.zeros((1, 3))


@pytest.mark.parametrize("dt", [0.0, -1e-3, np.nan, np.inf, "0.001", None, np.array([1e-3, 1e-3])])
def test_workspace_step_refuses_a_bad_dt(model, dt):
    with pytest.raises(ValueError, match=r"^dt: "):
        model.workspace(1).step(dt)


@pytest.mark.parametrize("steps", [-1, 1.5, np.nan, np.inf, "3", True, 10**30])
def test_workspace_step_refuses_bad_steps(model, steps):
    with pytest.raises(ValueError, match=r"^steps: "):
        model.workspace(1).step(1e-3, steps)


@pytest.mark.parametrize("how", [copy.deepcopy, lambda ws: pickle.loads(pickle.dumps(ws))], ids=["deepcopy", "pickle"])
def test_a_copied_workspace_is_independent_and_bit_identical(model, how):
    ws = model.workspace(1)
    ws.leg_forces[0] = 1000.0
    expected = ws.forward().copy()
    twin = how(ws)
    assert not np.shares_memory(twin.position, ws.position)
    np.testing.assert_array_equal(twin.forward(), expected)
    twin.position[0, 2] += 0.01
    twin.forward()
    np.testing.assert_array_equal(ws.forward(), expected)
    assert not twin.model.packed.flags.writeable  # the copy's model stays immutable


@pytest.mark.parametrize("how", [copy.deepcopy, lambda m: pickle.loads(pickle.dumps(m))], ids=["deepcopy", "pickle"])
def test_a_copied_model_gives_the_same_numbers(model, home, how):
    t, R, z = home
    forces = np.full(6, 1000.0)
    np.testing.assert_array_equal(how(model).forward(t, R, z, z, forces)[0], model.forward(t, R, z, z, forces)[0])


def test_scale_packed_names_a_wrong_or_read_only_out_row(model):
    from stewart_env.randomization import Randomization

    rnd = Randomization({"platform.mass": (0.8, 1.2)})
    with pytest.raises(ValueError, match=r"^out_row: "):
        rnd.scale_packed(model.packed[0], {"platform.mass": 1.0}, np.empty(3))
    with pytest.raises(ValueError, match=r"^out_row: read-only"):
        rnd.scale_packed(model.packed[0], {"platform.mass": 1.0}, model.packed[0])


# -- parameter arrays of any layout: the model and the bound workspace own a C-contiguous copy ----


def _churn():
    """Allocate and fill many arrays of a parameter row's size, so memory freed before is reused
    (a pointer into a freed copy then reads these numbers)."""
    return [np.full((1, se.dynamics.kernels.N_PARAMS), 1e3) for _ in range(200)]


PARAMETER_LAYOUTS = {
    "strided": lambda p: np.repeat(p, 2, axis=1)[:, ::2],
    "fortran": lambda p: np.asfortranarray(np.repeat(p, 2, axis=0))[:1],
    "float32": lambda p: p.astype(np.float32),
    "list": lambda p: p.tolist(),
}


@pytest.mark.parametrize("layout", list(PARAMETER_LAYOUTS))
def test_packed_rows_assigned_in_any_layout_give_the_numbers_of_a_plain_array(dasgupta, rng, layout):
    model = se.make_dynamics("improved", dasgupta)
    given = PARAMETER_LAYOUTS[layout](model.packed)
    plain = se.make_dynamics("improved", dasgupta)
    plain.packed = np.array(given, dtype=np.float64)  # the same numbers, C-contiguous float64
    model.packed = given
    assert model.packed.flags.c_contiguous and model.packed.dtype == np.float64 and not model.packed.flags.writeable
    assert isinstance(given, list) or not np.shares_memory(model.packed, given)
    t, R, v, w, F, W = random_batch(dasgupta, rng, 1)
    want = plain.workspace()
    ws = model.workspace()
    for bench in (want, ws):
        bench.set_state(t, R, v, w)
        bench.leg_forces[:] = F
    expected = want.forward().copy()
    _churn()
    assert np.array_equal(ws.forward(), expected)
    _churn()
    assert np.array_equal(ws.forward(), expected)
    assert np.array_equal(np.hstack(model.forward(t, R, v, w, F)), expected)


def test_bound_workspace_keeps_the_parameter_copy_it_was_given(dasgupta):
    """The compiled workspace given a parameter array it must convert (strided) holds the copy:
    its calls after the caller's temporary is gone still read the model's numbers."""
    from stewart_env import _core
    from stewart_env.dynamics.workspace import _ARRAYS

    model = se.make_dynamics("improved", dasgupta)
    want = model.workspace()
    want.leg_forces[0] = 150.0
    expected = want.forward().copy()
    arrays = {name: np.zeros((1,) + tail) for name, (tail, _) in _ARRAYS.items()}
    arrays["position"][0], arrays["rotation"][0] = want.position[0], want.rotation[0]
    arrays["leg_forces"][0] = 150.0
    bound = _core.BoundWorkspace(np.repeat(model.packed, 2, axis=1)[:, ::2], model.flags, *arrays.values())
    _churn()
    bound.forward()
    assert np.array_equal(arrays["acceleration"], expected)


@pytest.mark.parametrize(
    "value, message",
    [
        (None, r"^packed: expected an array of real numbers of shape \(1, \d+\), got None$"),
        ("masked", r"^packed: a masked array with 1 masked value"),
        (np.zeros((2, 3)), r"^packed: expected shape \(1, \d+\), got \(2, 3\)$"),
        ("nan", r"^packed: contains NaN"),
    ],
)
def test_assigning_packed_rows_refuses_what_is_not_a_row_of_numbers(dasgupta, value, message):
    model = se.make_dynamics("improved", dasgupta)
    before = model.packed
    if isinstance(value, str):
        value = (
            np.ma.masked_array(before, mask=np.arange(before.size).reshape(before.shape) == 3)
            if value == "masked"
            else np.where(np.arange(before.size) == 3, np.nan, before)
        )
    with pytest.raises(ValueError, match=message):
        model.packed = value
    assert model.packed is before
