"""The exact derivatives of the dynamics (stewart_env.dynamics.derivatives): the Jacobians of the
acceleration and of one control step agree with central differences on both models, every switch
and both forms, their values are forward's and the rollout's bit for bit, batches and thread counts
give the same bits, a singular pose is flagged NaN, and bad input is refused as forward refuses it."""

import numpy as np
import pytest

import stewart_env as se
from stewart_env.dynamics import derivatives
from stewart_env.dynamics.derivatives import central_differences

from physics_reference import random_state

pytestmark = pytest.mark.physics

# every base model and form, each switch alone, and all four together
MODELS = [
    "improved",
    "improved_centroidal",
    "classical",
    "improved+c1",
    "improved+c2",
    "improved+c3",
    "improved+c4",
    "improved_centroidal+c1+c2+c3+c4",
]


def moving_state(params, seed=0):
    """A moving state near home, leg forces near the holding forces and an external wrench."""
    rng = np.random.default_rng(seed)
    t, R, v, w = random_state(params, rng, speed=0.3)
    z = np.zeros(3)
    F = se.make_dynamics("improved", params).inverse(t, R, z, z, z, z) + rng.normal(scale=20.0, size=6)
    W = rng.normal(scale=5.0, size=6)
    return t, R, v, w, F, W


def assert_close(exact, differences, what):
    """exact and central differences agree to 1e-6 relative to the block's largest entry (entries
    that vanish by structure differ by the differences' rounding, so each is judged on its block's
    scale)."""
    scale = np.abs(exact).max()
    err = np.abs(exact - differences).max()
    assert err <= 1e-6 * scale, f"{what}: |exact - central| = {err:.3e}, scale {scale:.3e}"


@pytest.mark.parametrize("name", MODELS)
def test_acceleration_jacobians_match_central_differences(dasgupta, name):
    model = se.make_dynamics(name, dasgupta)
    t, R, v, w, F, W = moving_state(dasgupta)
    exact = model.acceleration_jacobians(t, R, v, w, F, W)
    cd = central_differences(model, t, R, v, w, F, external_wrench=W)
    for field in ("d_pose", "d_twist", "d_forces"):
        assert_close(getattr(exact, field), getattr(cd, field), f"{name} {field}")
    # the acceleration is forward's, bit for bit
    lin, ang = model.forward(t, R, v, w, F, W)
    assert np.array_equal(exact.acceleration, np.concatenate([lin, ang]))
    assert exact.finite


@pytest.mark.parametrize("name", ["improved", "improved_centroidal+c1+c3", "classical"])
def test_step_jacobians_match_central_differences_and_the_rollout(dasgupta, name):
    model = se.make_dynamics(name, dasgupta)
    t, R, v, w, F, W = moving_state(dasgupta, seed=1)
    exact = model.step_jacobians(t, R, v, w, F, 0.01, steps=10, external_wrench=W)
    cd = central_differences(model, t, R, v, w, F, 0.01, 10, W)
    assert_close(exact.A, cd.A, f"{name} A")
    assert_close(exact.B, cd.B, f"{name} B")
    # the next state is the rollout's of ten steps of 1 ms, bit for bit
    rolled = se.rollout(model, t, R, v, w, F, dt=0.001, steps=10, external_wrench=W)
    for mine, theirs in zip(exact.state, rolled):
        assert np.array_equal(mine, theirs)


def test_reflected_masses_enter_the_derivatives(simulator):
    model = se.make_dynamics("improved", simulator)
    t, R, v, w, F, W = moving_state(simulator, seed=2)
    m_r = np.array([30.0, 31.0, 32.0, 33.0, 34.0, 35.0])
    exact = model.acceleration_jacobians(t, R, v, w, F, W, reflected_mass=m_r)
    cd = central_differences(model, t, R, v, w, F, external_wrench=W, reflected_mass=m_r)
    for field in ("d_pose", "d_twist", "d_forces"):
        assert_close(getattr(exact, field), getattr(cd, field), f"reflected {field}")
    out = np.empty((1, 6))
    se.dynamics.kernels  # noqa: B018  (the package's kernels are loaded)
    from stewart_env import _core

    _core.forward_reflected_batch(
        model.packed, model.flags, t[None], R[None], v[None], w[None], F[None], W[None], m_r[None], out
    )
    assert np.array_equal(exact.acceleration, out[0])
    # the drives' inertia slows the platform: the forces' effect is smaller with it
    plain = model.acceleration_jacobians(t, R, v, w, F, W)
    assert np.linalg.norm(exact.d_forces) < np.linalg.norm(plain.d_forces)
    step = model.step_jacobians(t, R, v, w, F, 0.01, 5, W, reflected_mass=m_r)
    cd = central_differences(model, t, R, v, w, F, 0.01, 5, W, reflected_mass=m_r)
    assert_close(step.A, cd.A, "reflected A")
    assert_close(step.B, cd.B, "reflected B")


def test_the_tangent_coordinates_are_the_documented_ones(dasgupta):
    """A first-order move along each tangent coordinate, made by hand (dtheta on the left in {B}),
    predicts the next state's change as A says; the identity at a zero-length step's limit."""
    model = se.make_dynamics("improved", dasgupta)
    t, R, v, w, F, W = moving_state(dasgupta, seed=3)
    jac = model.step_jacobians(t, R, v, w, F, 0.01, 10, W)
    h = 1e-6
    phi = np.array([0.3, -0.5, 0.8]) * h
    moved = se.rollout(model, t, se.rotations.rotvec_to_matrix(phi) @ R, v, w, F, dt=0.001, steps=10, external_wrench=W)
    dtheta, _ = se.rotations.rotation_error(moved[1], jac.state.rotation)
    predicted = jac.A[3:6, 3:6] @ phi
    # first order in h: the difference is O(h^2) relative, far below 1e-4
    np.testing.assert_allclose(dtheta, predicted, rtol=1e-4, atol=1e-4 * np.abs(predicted).max())
    # the position rows' velocity block is dt I to first order in dt (x_next = x + dt v + ...)
    np.testing.assert_allclose(jac.A[0:3, 6:9], 0.01 * np.eye(3), atol=2e-4)  # O(dt^2) terms: 1e-4 measured scale


def same_bytes(a, b):
    """Bit for bit, the sign of a zero included (np.array_equal counts -0.0 equal to 0.0)."""
    a, b = np.asarray(a), np.asarray(b)
    return a.shape == b.shape and a.tobytes() == b.tobytes()


def test_batches_and_threads_give_the_same_bits(dasgupta):
    model = se.make_dynamics("improved", dasgupta)
    states = [moving_state(dasgupta, seed=s) for s in range(24)]
    t, R, v, w, F, W = (np.stack(x) for x in zip(*states))
    before = se.get_num_threads()
    try:
        se.set_num_threads(1)
        one_acc = model.acceleration_jacobians(t, R, v, w, F, W)
        one_step = model.step_jacobians(t, R, v, w, F, 0.01, 2, W)
        se.set_num_threads(2)
        two_acc = model.acceleration_jacobians(t, R, v, w, F, W)
        two_step = model.step_jacobians(t, R, v, w, F, 0.01, 2, W)
    finally:
        se.set_num_threads(before)
    for a, b in zip(one_acc, two_acc):
        assert same_bytes(a, b)
    assert same_bytes(one_step.A, two_step.A) and same_bytes(one_step.B, two_step.B)
    alone = model.acceleration_jacobians(t[5], R[5], v[5], w[5], F[5], W[5])
    for a, b in zip(alone, two_acc):
        assert same_bytes(a, b[5])
    alone = model.step_jacobians(t[7], R[7], v[7], w[7], F[7], 0.01, 2, W[7])
    assert same_bytes(alone.A, two_step.A[7]) and same_bytes(alone.B, two_step.B[7])
    assert one_acc.finite.shape == (24,) and one_acc.finite.all() and one_step.finite.all()


@pytest.mark.parametrize("name", MODELS)
def test_a_row_in_a_block_of_lanes_is_the_row_alone(simulator, name):
    """Rows of a batch run eight to a vector (the last few alone): each row's numbers, zeros' signs
    included, are those it has alone, on every model, at rest (where many derivatives vanish) and
    moving, with reflected masses that differ from row to row (some zero)."""
    model = se.make_dynamics(name, simulator)
    states = [moving_state(simulator, seed=s) for s in range(11)]
    t, R, v, w, F, W = (np.stack(x) for x in zip(*states))
    v[:3] = 0.0  # rows at rest
    w[:3] = 0.0
    W[1] = 0.0
    m_r = np.zeros((11, 6))
    m_r[4:] = np.linspace(5.0, 40.0, 6)
    m_r[6, 2] = 0.0
    batch_acc = model.acceleration_jacobians(t, R, v, w, F, W, reflected_mass=m_r)
    batch_step = model.step_jacobians(t, R, v, w, F, 0.01, 3, W, reflected_mass=m_r)
    for b in (0, 1, 4, 6, 9, 10):  # in the first block of eight, and among the rows left over
        acc = model.acceleration_jacobians(t[b], R[b], v[b], w[b], F[b], W[b], reflected_mass=m_r[b])
        for a, x in zip(acc, batch_acc):
            assert same_bytes(a, x[b]), b
        step = model.step_jacobians(t[b], R[b], v[b], w[b], F[b], 0.01, 3, W[b], reflected_mass=m_r[b])
        for a, x in zip(step, batch_step):
            if isinstance(a, tuple):
                for p, q in zip(a, x):
                    assert same_bytes(p, q[b]), b
            else:
                assert same_bytes(a, x[b]), b


def test_pinned_values(dasgupta):
    """A few entries at one state to 12 digits: a change of the kernels or of the AD shows here."""
    model = se.make_dynamics("improved", dasgupta)
    t, R, v, w, F, W = moving_state(dasgupta, seed=4)
    acc = model.acceleration_jacobians(t, R, v, w, F, W)
    step = model.step_jacobians(t, R, v, w, F, 0.01, 10, W)
    got = [acc.d_pose[0, 0], acc.d_pose[5, 3], acc.d_twist[2, 4], acc.d_forces[1, 2], step.A[3, 9], step.B[8, 5]]
    np.testing.assert_allclose(got, PINNED, rtol=1e-12)  # the numbers' own rounding, across targets


PINNED = [5.197698505259, 2.293034033741, -0.04141672927779, 0.01759012417375, 0.01002164770764, 0.0001082436013059]


def singular_state(params):
    """A pose with leg 0 along its U joint's fixed axis (k x e = 0): no leg frame there."""
    R = np.eye(3)
    k = params.hooke_axes[0]
    L = np.linalg.norm(params.home_position + params.platform_joints[0] - params.base_joints[0])
    t = params.base_joints[0] - params.platform_joints[0] + L * k
    return t, R


def test_a_singular_pose_is_flagged_not_a_silent_wrong_jacobian(dasgupta):
    model = se.make_dynamics("improved", dasgupta)
    t, R = singular_state(dasgupta)
    z = np.zeros(3)
    F = np.full(6, 150.0)
    lin, _ = model.forward(t, R, z, z, F)
    assert not np.isfinite(lin).all()  # forward's own result there: not finite
    out = model.acceleration_jacobians(t, R, z, z, F)
    assert not out.finite
    assert all(np.isnan(x).all() for x in out)
    step = model.step_jacobians(t, R, z, z, F, 0.01)
    assert not step.finite and np.isnan(step.A).all() and np.isnan(step.B).all()
    assert all(np.isnan(x).all() for x in step.state)
    # in a batch only the singular row is NaN
    t2, R2, v2, w2, F2, _ = moving_state(dasgupta)
    batch = model.acceleration_jacobians(
        np.stack([t, t2]), np.stack([R, R2]), np.stack([z, v2]), np.stack([z, w2]), np.stack([F, F2])
    )
    assert batch.finite.tolist() == [False, True]
    assert np.isfinite(batch.d_pose[1]).all() and np.isnan(batch.d_pose[0]).all()


def forward_error(model, *args):
    with pytest.raises(ValueError) as err:
        model.forward(*args)
    return str(err.value)


BAD = {
    "nan position": (0, lambda x: np.array([np.nan, 0.0, 0.4])),
    "wrong shape": (2, lambda x: np.zeros(4)),
    "complex": (4, lambda x: x.astype(complex)),
    "text": (4, lambda x: "forces"),
    "not a rotation": (1, lambda x: 2.0 * x),
    "None": (3, lambda x: None),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_input_is_refused_as_forward_refuses_it(dasgupta, case):
    model = se.make_dynamics("improved", dasgupta)
    t, R, v, w, F, W = moving_state(dasgupta)
    args = [t, R, v, w, F]
    where, bad = BAD[case]
    args[where] = bad(args[where])
    message = forward_error(model, *args)
    with pytest.raises(ValueError, match=None) as err:
        model.acceleration_jacobians(*args)
    assert str(err.value) == message
    with pytest.raises(ValueError) as err:
        model.step_jacobians(*args, 0.01)
    assert str(err.value) == message


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"dt": 0.0}, "dt"),
        ({"dt": np.inf}, "dt"),
        ({"dt": "0.01"}, "dt"),
        ({"steps": 0}, "steps"),
        ({"steps": True}, "steps"),
        ({"steps": 1.5}, "steps"),
    ],
)
def test_bad_step_arguments_name_themselves(dasgupta, kwargs, name):
    model = se.make_dynamics("improved", dasgupta)
    t, R, v, w, F, _ = moving_state(dasgupta)
    args = {"dt": 0.01, "steps": 1} | kwargs
    with pytest.raises(ValueError, match=rf"^{name}\b"):
        model.step_jacobians(t, R, v, w, F, **args)


def test_bad_reflected_mass_is_named(dasgupta):
    model = se.make_dynamics("improved", dasgupta)
    t, R, v, w, F, _ = moving_state(dasgupta)
    with pytest.raises(ValueError, match="^reflected_mass"):
        model.acceleration_jacobians(t, R, v, w, F, reflected_mass=-np.ones(6))
    with pytest.raises(ValueError, match="^reflected_mass"):
        model.acceleration_jacobians(t, R, v, w, F, reflected_mass=np.ones(5))


def test_results_are_the_documented_named_tuples(dasgupta):
    model = se.make_dynamics("improved", dasgupta)
    t, R, v, w, F, W = moving_state(dasgupta)
    acc = model.acceleration_jacobians(t, R, v, w, F)
    assert isinstance(acc, derivatives.AccelerationJacobians) and acc.acceleration.shape == (6,)
    assert acc.d_pose.shape == acc.d_twist.shape == acc.d_forces.shape == (6, 6)
    step = model.step_jacobians(t, R, v, w, F, 0.01)
    assert isinstance(step.state, se.PlatformState) and step.state.rotation.shape == (3, 3)
    assert step.A.shape == (12, 12) and step.B.shape == (12, 6)
    assert se.dynamics.AccelerationJacobians is derivatives.AccelerationJacobians


def test_the_bindings_take_converted_arrays_and_check_shapes(dasgupta):
    """Strided, Fortran-ordered and float32 inputs give the numbers of C-contiguous float64 ones (the
    converted copies held while read: tests/dynamics/test_sanitizer.py runs this under
    AddressSanitizer); an array of the wrong shape is named."""
    from stewart_env import _core

    model = se.make_dynamics("improved", dasgupta)
    states = [moving_state(dasgupta, seed=s) for s in range(3)]
    t, R, v, w, F, W = (np.stack(x) for x in zip(*states))
    acc, jac, finite = np.empty((3, 6)), np.empty((3, 6, 18)), np.empty(3, dtype=bool)
    _core.acceleration_jacobian_batch(model.packed, model.flags, t, R, v, w, F, W, None, acc, jac, finite)
    wide = np.zeros((3, 12))
    wide[:, ::2] = F
    acc2, jac2 = np.empty((3, 6)), np.empty((3, 6, 18))
    _core.acceleration_jacobian_batch(
        np.asfortranarray(model.packed),
        model.flags,
        t,
        np.asfortranarray(R),
        v,
        w,
        wide[:, ::2],
        W,
        None,
        acc2,
        jac2,
        finite,
    )
    assert np.array_equal(acc, acc2) and np.array_equal(jac, jac2)
    m_r = np.full((1, 6), 20.0, dtype=np.float32)
    _core.acceleration_jacobian_batch(model.packed, model.flags, t, R, v, w, F, W, m_r, acc2, jac2, finite)
    assert finite.all() and not np.array_equal(jac, jac2)
    nxt = [np.empty((3, 3)), np.empty((3, 3, 3)), np.empty((3, 3)), np.empty((3, 3))]
    with pytest.raises(ValueError, match="leg_forces: expected shape"):
        _core.step_jacobian_batch(
            model.packed, model.flags, t, R, v, w, F[:, :5], W, None, 0.01, 1, *nxt, np.empty((3, 12, 18)), finite
        )
    with pytest.raises(ValueError, match="jac: expected shape"):
        _core.step_jacobian_batch(
            model.packed, model.flags, t, R, v, w, F, W, None, 0.01, 1, *nxt, np.empty((3, 6, 18)), finite
        )
    with pytest.raises(ValueError, match="reflected_mass: expected 1 or N rows"):
        _core.acceleration_jacobian_batch(
            model.packed, model.flags, t, R, v, w, F, W, np.ones((2, 6)), acc, jac, finite
        )
