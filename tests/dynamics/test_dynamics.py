"""Dynamics: conservation laws, statics by virtual work, agreement between formulations."""

import numpy as np
import pytest

import stewart_env as se
from stewart_env.params import Damping, RigidBody

from physics_reference import dissipated_power, kinetic_energy, potential_energy, random_state, rotvec_matrix

pytestmark = pytest.mark.physics

ALL_MODELS = [
    "improved",
    "improved_centroidal",
    "classical",
    "improved+c1",
    "improved+c2",
    "improved+c3",
    "improved+c4",
    "improved_centroidal+c1+c3",
]


@pytest.fixture(params=["dasgupta", "simulator"])
def platform(request):
    return request.getfixturevalue(request.param)


def holding_forces(model, t, R):
    z = np.zeros(3)
    return model.inverse(t, R, z, z, z, z)


def without_friction(params):
    return params.replace(damping=Damping(0.0, 0.0, 0.0))


def energy_trajectory(model, state, F, W, dt, steps, every):
    """States every `every` RK4 steps along a trajectory."""
    out = [state]
    for _ in range(steps // every):
        state = se.rollout(model, *state, F, dt=dt, steps=every, external_wrench=W)
        out.append(state)
    return out


def test_energy_is_conserved_without_friction(platform, rng):
    params = without_friction(platform)
    model = se.make_dynamics("improved", params)
    t, R, v, w = random_state(params, rng, speed=0.1)
    F = holding_forces(model, t, R) * 1.02 + rng.normal(scale=0.01, size=6) * np.abs(holding_forces(model, t, R))
    F_ext = rng.normal(scale=0.05 * params.platform.mass, size=3)
    W = np.concatenate([F_ext, np.zeros(3)])
    traj = energy_trajectory(model, (t, R, v, w), F, W, dt=1e-3, steps=300, every=10)

    def energy(s):
        lengths = se.inverse_kinematics(params, s[0], s[1])[0]
        # actuator forces and the constant external force at P are conservative
        return kinetic_energy(params, *s) + potential_energy(params, s[0], s[1]) - F @ lengths - F_ext @ s[0]

    E = np.array([energy(s) for s in traj])
    T0 = max(kinetic_energy(params, *s) for s in traj)
    assert T0 > 0.05  # J: the trajectory really moves
    # RK4 at dt = 1 ms: local error O(dt^5) per step, far below 1e-8 of the kinetic energy scale
    assert np.abs(E - E[0]).max() < 1e-8 * T0


def test_classical_model_does_not_conserve_the_true_energy(dasgupta, rng):
    params = without_friction(dasgupta)
    model = se.make_dynamics("classical", params)
    t, R, v, w = random_state(params, rng, speed=0.3)
    F = holding_forces(se.make_dynamics("improved", params), t, R)
    traj = energy_trajectory(model, (t, R, v, w), F, np.zeros(6), dt=1e-3, steps=200, every=10)

    def energy(s):
        lengths = se.inverse_kinematics(params, s[0], s[1])[0]
        return kinetic_energy(params, *s) + potential_energy(params, s[0], s[1]) - F @ lengths

    E = np.array([energy(s) for s in traj])
    T0 = max(kinetic_energy(params, *s) for s in traj)
    # the classical simplifications break energy balance by far more than integration error
    assert np.abs(E - E[0]).max() > 1e-4 * T0


def test_power_balance_with_friction(platform, rng):
    d = platform.damping
    # friction scaled up so the dissipated energy is large next to the integration error
    params = platform.replace(
        damping=Damping(max(d.universal, 1e-3) * 500, max(d.prismatic, 1e-3) * 500, max(d.spherical, 1e-3) * 500)
    )
    model = se.make_dynamics("improved", params)
    t, R, v, w = random_state(params, rng, speed=0.2)
    F = holding_forces(model, t, R)
    M_ext = rng.normal(scale=0.2 * params.platform.mass, size=3)
    W = np.concatenate([np.zeros(3), M_ext])
    dt, steps = 2e-4, 1000
    traj = energy_trajectory(model, (t, R, v, w), F, W, dt=dt, steps=steps, every=1)

    def energy(s):
        lengths = se.inverse_kinematics(params, s[0], s[1])[0]
        return kinetic_energy(params, *s) + potential_energy(params, s[0], s[1]) - F @ lengths

    E = np.array([energy(s) for s in traj])
    # dE/dt = M_ext . w - friction power, integrated with Simpson's rule over the samples
    rate = np.array([M_ext @ s[3] - dissipated_power(params, *s) for s in traj])
    integral = dt / 3 * (rate[0] + rate[-1] + 4 * rate[1:-1:2].sum() + 2 * rate[2:-1:2].sum())
    lost = dt * np.abs(rate).sum()
    assert lost > 1e-3 * max(kinetic_energy(params, *s) for s in traj)  # friction matters here
    # Simpson and RK4 errors are O(dt^4): 1e-6 of the energy exchanged
    assert abs((E[-1] - E[0]) - integral) < 1e-6 * lost


def potential_gradient(params, t, R, h=1e-6):
    """dV/d[t; phi] for R = exp([phi]x) R, central differences (error O(h^2) ~ 1e-12)."""
    grad = np.zeros(6)
    for j in range(6):
        d = np.zeros(6)
        d[j] = h
        Vp = potential_energy(params, t + d[:3], rotvec_matrix(d[3:]) @ R)
        Vm = potential_energy(params, t - d[:3], rotvec_matrix(-d[3:]) @ R)
        grad[j] = (Vp - Vm) / (2 * h)
    return grad


@pytest.mark.parametrize("name", ["improved", "improved_centroidal", "improved+c1", "improved+c3", "improved+c4"])
def test_statics_satisfy_virtual_work(platform, rng, name):
    model = se.make_dynamics(name, platform)
    for _ in range(3):
        t, R, _, _ = random_state(platform, rng)
        F = holding_forces(model, t, R)
        J = se.jacobian(platform, t, R)
        grad = potential_gradient(platform, t, R)
        # virtual work: J^T F = grad V; the difference quotient is good to ~1e-9 relative
        np.testing.assert_allclose(J.T @ F, grad, rtol=0, atol=1e-7 * np.abs(grad).max())


@pytest.mark.parametrize("name", ["classical", "improved+c2"])
def test_constraint_moment_along_the_leg_misses_virtual_work(dasgupta, rng, name):
    model = se.make_dynamics(name, dasgupta)
    t, R, _, _ = random_state(dasgupta, rng)
    F = holding_forces(model, t, R)
    J = se.jacobian(dasgupta, t, R)
    grad = potential_gradient(dasgupta, t, R)
    # off-axis leg CoMs give the leg weight a moment about the leg axis that C2 drops
    assert np.abs(J.T @ F - grad).max() > 1e-3 * np.abs(grad).max()


def test_both_improved_forms_agree(platform, rng):
    a = se.make_dynamics("improved", platform)
    b = se.make_dynamics("improved_centroidal", platform)
    for _ in range(10):
        state = random_state(platform, rng, speed=0.5)
        F = holding_forces(a, *state[:2]) + rng.normal(scale=0.1, size=6) * np.abs(holding_forces(a, *state[:2]))
        W = rng.normal(size=6) * platform.platform.mass
        la, aa = a.forward(*state, F, external_wrench=W)
        lb, ab = b.forward(*state, F, external_wrench=W)
        acc_a, acc_b = np.concatenate([la, aa]), np.concatenate([lb, ab])
        # two formulas for one dynamics: rounding only
        assert np.abs(acc_a - acc_b).max() <= 1e-10 * np.abs(acc_a).max()


@pytest.mark.parametrize("name", ALL_MODELS)
def test_inverse_undoes_forward(platform, rng, name):
    model = se.make_dynamics(name, platform)
    for _ in range(5):
        state = random_state(platform, rng, speed=0.5)
        F = holding_forces(model, *state[:2]) * rng.uniform(0.5, 1.5, size=6)
        W = rng.normal(size=6) * platform.platform.mass
        lin, ang = model.forward(*state, F, external_wrench=W)
        F_back = model.inverse(*state, lin, ang, external_wrench=W)
        # a 6x6 solve with condition < 10 and back: rounding of the largest force term
        np.testing.assert_allclose(F_back, F, rtol=0, atol=1e-10 * np.abs(F).max())


def _massless_legs(params, platform_com):
    massless = RigidBody(0.0, np.zeros(3), np.zeros((3, 3)))
    body = RigidBody(params.platform.mass, platform_com, params.platform.inertia)
    return params.replace(upper_leg=massless, lower_leg=massless, platform=body, damping=Damping(0.0, 0.0, 0.0))


def test_massless_frictionless_legs_give_one_answer_for_all_models(platform, rng):
    # C4 also touches the platform's own equation unless its CoM is at P; with the CoM there,
    # nothing is left for any simplification to change
    params = _massless_legs(platform, np.zeros(3))
    ref = se.make_dynamics("improved", params)
    for _ in range(5):
        state = random_state(params, rng, speed=0.5)
        F = rng.normal(size=6) * params.platform.mass * 10
        acc_ref = np.concatenate(ref.forward(*state, F))
        for name in ALL_MODELS[1:]:
            acc = np.concatenate(se.make_dynamics(name, params).forward(*state, F))
            np.testing.assert_allclose(acc, acc_ref, rtol=0, atol=1e-10 * np.abs(acc_ref).max())  # rounding


def test_with_massless_legs_only_the_platform_simplification_acts(dasgupta, rng):
    params = _massless_legs(dasgupta, dasgupta.platform.com)
    state = random_state(params, rng, speed=0.5)
    F = rng.normal(size=6) * params.platform.mass * 10
    acc_ref = np.concatenate(se.make_dynamics("improved", params).forward(*state, F))
    for name in ["improved+c1+c2+c3", "improved_centroidal+c1+c2+c3"]:
        acc = np.concatenate(se.make_dynamics(name, params).forward(*state, F))
        np.testing.assert_allclose(acc, acc_ref, rtol=0, atol=1e-10 * np.abs(acc_ref).max())  # rounding
    acc_c4 = np.concatenate(se.make_dynamics("improved+c4", params).forward(*state, F))
    assert np.abs(acc_c4 - acc_ref).max() > 1e-3 * np.abs(acc_ref).max()  # an off-P CoM: percents, not rounding


@pytest.mark.parametrize("name", ["classical", "improved+c1", "improved+c2", "improved+c3", "improved+c4"])
def test_each_simplification_changes_the_dynamics_of_the_example(dasgupta, rng, name):
    ref = se.make_dynamics("improved", dasgupta)
    model = se.make_dynamics(name, dasgupta)
    state = random_state(dasgupta, rng, speed=0.5)
    F = holding_forces(ref, *state[:2]) * 1.2
    acc_ref = np.concatenate(ref.forward(*state, F))
    acc = np.concatenate(model.forward(*state, F))
    # legs with mass, spin and off-axis CoMs: each simplification moves the answer by > 0.1 %
    assert np.abs(acc - acc_ref).max() > 1e-3 * np.abs(acc_ref).max()


def _assert_each_row_equals_its_single_call(model, t, R, v, w, F):
    """forward, inverse and a 20-step rollout of a batch, row by row against one-row calls on that row's params."""
    lin, ang = model.forward(t, R, v, w, F)
    Fi = model.inverse(t, R, v, w, lin, ang)
    end = se.rollout(model, t, R, v, w, F, dt=1e-3, steps=20)
    for b in range(len(t)):
        single = model if len(model.params) == 1 else se.make_dynamics(model.name, model.params[b])
        l1, a1 = single.forward(t[b], R[b], v[b], w[b], F[b])
        # the same arithmetic per row, serial or on any thread: bit-identical, no tolerance
        assert np.array_equal(l1, lin[b]) and np.array_equal(a1, ang[b])
        assert np.array_equal(single.inverse(t[b], R[b], v[b], w[b], l1, a1), Fi[b])
        e1 = se.rollout(single, t[b], R[b], v[b], w[b], F[b], dt=1e-3, steps=20)
        for x, y in zip(e1, end):
            assert np.array_equal(x, y[b])


def test_batched_calls_equal_single_calls(dasgupta, simulator, rng):
    n = 7
    params = [
        dasgupta.replace(
            platform=RigidBody(dasgupta.platform.mass * (1 + 0.1 * i), dasgupta.platform.com, dasgupta.platform.inertia)
        )
        for i in range(n)
    ]
    for model in (se.make_dynamics("improved", dasgupta), se.make_dynamics("classical", params)):
        states = [random_state(dasgupta, rng) for _ in range(n)]
        t, R, v, w = (np.array(x) for x in zip(*states))
        _assert_each_row_equals_its_single_call(model, t, R, v, w, rng.normal(size=(n, 6)) * 200 + 180)


@pytest.mark.parametrize("name", ["improved", "classical"])
def test_large_batches_equal_single_calls(dasgupta, rng, name):
    """A batch of many rows gives each row the single-row answer: a row's arithmetic does not depend on the batch."""
    n = 19
    model = se.make_dynamics(name, dasgupta)
    t, R, v, w = (np.array(x) for x in zip(*(random_state(dasgupta, rng) for _ in range(n))))
    F = np.array([holding_forces(model, t[b], R[b]) for b in range(n)]) * rng.uniform(0.9, 1.1, (n, 6))
    _assert_each_row_equals_its_single_call(model, t, R, v, w, F)


def test_single_platform_calls_agree_whatever_the_argument_types(dasgupta, rng):
    """float64 arrays (checked and solved in one compiled call) and lists (checked in Python, then
    the batch kernel) give the same numbers bit for bit."""
    model = se.make_dynamics("improved", dasgupta)
    t, R, v, w = random_state(dasgupta, rng, speed=0.5)
    F = holding_forces(model, t, R) * 1.1
    W = rng.normal(size=6)
    lin, ang = model.forward(t, R, v, w, F, W)
    lin_l, ang_l = model.forward(t.tolist(), R.tolist(), v.tolist(), w.tolist(), F.tolist(), W.tolist())
    assert np.array_equal(lin, lin_l) and np.array_equal(ang, ang_l)
    Fi = model.inverse(t, R, v, w, lin, ang, W)
    assert np.array_equal(
        Fi, model.inverse(t.tolist(), R.tolist(), v.tolist(), w.tolist(), lin.tolist(), ang.tolist(), W.tolist())
    )
    np.testing.assert_allclose(Fi, F, rtol=0, atol=1e-9 * np.abs(F).max())  # solving both ways: rounding


def test_rk4_converges_at_fourth_order(dasgupta, rng):
    model = se.make_dynamics("improved", dasgupta)
    state = random_state(dasgupta, rng, speed=0.3)
    F = holding_forces(model, *state[:2]) * 1.1
    ref = se.rollout(model, *state, F, dt=0.25e-3, steps=800)
    errors = [
        np.abs(se.rollout(model, *state, F, dt=dt, steps=round(0.2 / dt))[0] - ref[0]).max() for dt in (4e-3, 2e-3)
    ]
    # halving dt divides a 4th-order method's error by ~16
    assert 10 < errors[0] / errors[1] < 20


def test_bad_arguments_name_what_is_wrong(dasgupta):
    model = se.make_dynamics("improved", dasgupta)
    t, R, z = dasgupta.home_position, np.eye(3), np.zeros(3)
    with pytest.raises(ValueError, match="leg_forces: expected shape"):
        model.forward(t, R, z, z, np.zeros(5))
    with pytest.raises(ValueError, match="velocity: contains NaN"):
        model.forward(t, R, [0, np.nan, 0], z, np.zeros(6))
    with pytest.raises(ValueError, match="rotation: not a rotation"):
        model.forward(t, 2 * R, z, z, np.zeros(6))
    with pytest.raises(ValueError, match="batch sizes disagree"):
        model.forward(np.tile(t, (3, 1)), R, z, z, np.zeros((2, 6)))
    with pytest.raises(ValueError, match="unknown model 'newton'"):
        se.make_dynamics("newton", dasgupta)
    with pytest.raises(ValueError, match="unknown switch 'c5'"):
        se.make_dynamics("improved+c5", dasgupta)
    with pytest.raises(ValueError, match=r"^dt: expected a finite number > 0, got 0.0"):
        se.rollout(model, t, R, z, z, np.zeros(6), dt=0.0)


def _entry_points(model, params):
    """Every public call that takes a platform state, as f(position, rotation, velocity)."""
    z, F = np.zeros(3), np.full(6, 180.0)
    return {
        "forward": lambda t, R, v: model.forward(t, R, v, z, F),
        "inverse": lambda t, R, v: model.inverse(t, R, v, z, z, z),
        "mass_and_bias": lambda t, R, v: model.mass_and_bias(t, R, v, z),
        "mass_matrix": lambda t, R, v: model.mass_matrix(t, R, v, z),
        "bias": lambda t, R, v: model.bias(t, R, v, z),
        "rollout": lambda t, R, v: se.rollout(model, t, R, v, z, F, steps=1),
        "leg_kinematics": lambda t, R, v: se.leg_kinematics(model, t, R, v),
        "leg_kinematics of params": lambda t, R, v: se.leg_kinematics(params, t, R, v),
        "jacobian": lambda t, R, v: se.jacobian(model, t, R),
        "inverse_kinematics": lambda t, R, v: se.inverse_kinematics(params, t, R),
        "workspace.set_state": lambda t, R, v: model.workspace(len(t) if np.ndim(t) == 2 else 1).set_state(t, R, v, z),
    }


NOT_ROTATIONS = {
    "scaled": 2 * np.eye(3),
    "reflection": np.diag([1.0, 1.0, -1.0]),
    "sheared": np.eye(3) + np.triu(np.full((3, 3), 1e-5), 1),
}


@pytest.mark.parametrize("entry", list(_entry_points(None, None)))
def test_every_entry_point_checks_its_arguments_alike(dasgupta, entry):
    call = _entry_points(se.make_dynamics("improved", dasgupta), dasgupta)[entry]
    t, R, v = dasgupta.home_position, se.rpy_to_matrix([0.02, -0.03, 0.05]), np.zeros(3)
    for bad in NOT_ROTATIONS.values():
        with pytest.raises(ValueError, match="rotation: not a rotation matrix"):
            call(t, bad, v)
        with pytest.raises(ValueError, match=r"rotation: not a rotation matrix in batch rows \[1\]"):
            call(np.stack([t, t]), np.stack([R, bad]), np.zeros((2, 3)))
    with pytest.raises(ValueError, match="rotation: contains NaN"):
        call(t, np.where(np.eye(3) > 0, np.nan, R), v)
    with pytest.raises(ValueError, match="position: expected shape"):
        call(t[:2], R, v)
    with pytest.raises(ValueError, match="position: contains NaN or inf"):
        call(t + [0, np.inf, 0], R, v)
    if entry not in ("jacobian", "inverse_kinematics"):
        with pytest.raises(ValueError, match="velocity: expected shape"):
            call(t, R, np.zeros(4))
    # rounding far above float64's but within the stated tolerance (a rotation rebuilt from
    # float32 numbers) is accepted
    call(t, R + 1e-8 * np.array([[0.3, -0.7, 0.2], [0.5, 0.1, -0.4], [-0.2, 0.6, 0.8]]), v)


def test_forward_kinematics_checks_its_guess_like_every_entry_point(dasgupta):
    lengths = se.inverse_kinematics(dasgupta, dasgupta.home_position, np.eye(3))[0]
    with pytest.raises(ValueError, match="rotation_guess: not a rotation matrix"):
        se.forward_kinematics(dasgupta, lengths, dasgupta.home_position, np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(ValueError, match="position_guess: contains NaN"):
        se.forward_kinematics(dasgupta, lengths, [0.0, np.nan, 1.0], np.eye(3))
    with pytest.raises(ValueError, match="leg_lengths: expected an array of numbers of shape"):
        se.forward_kinematics(dasgupta, "1.2 m", dasgupta.home_position, np.eye(3))
    with pytest.raises(ValueError, match="leg_lengths: expected six positive lengths"):
        se.forward_kinematics(dasgupta, -lengths, dasgupta.home_position, np.eye(3))


def test_rollout_reports_a_state_that_stops_being_finite(dasgupta):
    model = se.make_dynamics("improved", dasgupta)
    # a huge force throws the platform through a singular pose within a few steps
    with pytest.raises(FloatingPointError, match="non-finite in batch rows"):
        se.rollout(
            model, dasgupta.home_position, np.eye(3), np.zeros(3), np.zeros(3), np.full(6, -1e9), dt=1e-3, steps=2000
        )


def test_replacing_rows_equals_packing_every_row(dasgupta):
    heavier = [
        dasgupta.replace(
            platform=RigidBody(dasgupta.platform.mass * f, dasgupta.platform.com, dasgupta.platform.inertia)
        )
        for f in (1.1, 1.2, 1.3, 1.4)
    ]
    model = se.make_dynamics("improved", [dasgupta] * 4)
    swapped = model.with_rows([1, 3], [heavier[1], heavier[3]])
    expected = se.make_dynamics("improved", [dasgupta, heavier[1], dasgupta, heavier[3]])
    assert np.array_equal(swapped.packed, expected.packed) and swapped.params == expected.params
    assert np.array_equal(model.packed, se.make_dynamics("improved", [dasgupta] * 4).packed)  # original untouched
    with pytest.raises(ValueError, match="rows: 4 is outside"):
        model.with_rows([4], [dasgupta])


# forward, inverse and a 50-step rollout on dasgupta1998, recorded before the kernels were
# compiled with fused multiply-adds, reciprocals and inlined helpers (the state is set in the test below)
RECORDED = {
    "improved": (
        [
            1.622555526931937,
            -1.2763114373593376,
            2.706567549557876,
            -11.817689396046802,
            -14.087960659715366,
            29.1955333523591,
        ],
        [
            197.15227867394682,
            198.69827803365501,
            213.5173375923025,
            133.79595922166493,
            191.11850383512973,
            173.6679807021337,
        ],
        [0.029034671059815977, -0.032457522102736315, 0.457605418075476],
        [-1.2124120325252425, 0.007847139743641419, 2.1441374807167555],
    ),
    "improved_centroidal": (
        [
            1.6225555269319363,
            -1.2763114373593372,
            2.706567549557876,
            -11.817689396046807,
            -14.087960659715373,
            29.1955333523591,
        ],
        [
            197.1522786739467,
            198.69827803365501,
            213.5173375923025,
            133.79595922166487,
            191.11850383512973,
            173.6679807021337,
        ],
        [0.029034671059815977, -0.032457522102736315, 0.457605418075476],
        [-1.2124120325252425, 0.007847139743641488, 2.1441374807167555],
    ),
    "classical": (
        [
            1.4654019006129273,
            -1.1530401198606512,
            2.5001572116346296,
            -9.708325734226683,
            -11.400104479346558,
            26.299229203406973,
        ],
        [
            201.87094609107103,
            199.0525664283846,
            213.4633853418701,
            137.69488590639327,
            189.67787498903098,
            178.7589391041661,
        ],
        [0.028831654384122593, -0.03231768044324798, 0.4573107138063616],
        [-1.074377112004858, 0.13742133516854543, 1.9850547173914879],
    ),
    "improved+c1+c3": (
        [
            1.4797658888853749,
            -1.1548935360441748,
            2.4912058228004317,
            -9.24812575099189,
            -11.197769548372229,
            26.69839781808992,
        ],
        [
            202.31467653307254,
            198.87398757763003,
            214.5730796088506,
            136.9344746984935,
            191.10458595890293,
            176.63150087122415,
        ],
        [0.028857600652450494, -0.032300853716663726, 0.457304484969044],
        [-1.055055402155021, 0.15170602225347138, 2.002274073579269],
    ),
}


@pytest.mark.parametrize("name", list(RECORDED))
def test_compiled_kernels_reproduce_recorded_values(dasgupta, name):
    model = se.make_dynamics(name, dasgupta)
    t = dasgupta.home_position + np.array([0.012, -0.021, 0.034])
    R = se.rpy_to_matrix(np.array([0.05, -0.08, 0.11]))
    v, w = np.array([0.3, -0.2, 0.4]), np.array([-0.5, 0.7, 0.6])
    F = np.array([150.0, 260.0, 90.0, 310.0, 205.0, 170.0])
    W = np.array([12.0, -8.0, 30.0, 1.5, -2.0, 0.7])
    end = se.rollout(model, t, R, v, w, F, dt=1e-3, steps=50, external_wrench=W)
    computed = (
        np.concatenate(model.forward(t, R, v, w, F, W)),
        model.inverse(t, R, v, w, np.array([0.5, -1.0, 2.0]), np.array([3.0, -1.5, 0.8]), W),
        end[0],
        end[3],
    )
    for got, recorded in zip(computed, RECORDED[name]):
        # fused multiply-adds and reciprocals change each operation by at most an ulp; a solve with
        # cond(M) ~ 10 and 50 RK4 steps keep the sum near 1e-15 of the largest component
        assert np.abs(got - recorded).max() <= 1e-14 * np.abs(recorded).max()


def test_kernels_still_propagate_nan_and_inf(dasgupta):
    from stewart_env.dynamics import kernels as K

    model = se.make_dynamics("improved", dasgupta)
    state = [np.array([x]) for x in (dasgupta.home_position, np.eye(3), np.zeros(3), np.zeros(3))]
    out = np.zeros((2, 6))  # finite, so a row the kernel leaves unwritten fails the assertion
    for b, bad in enumerate((np.nan, np.inf)):
        v = np.array([[0.0, bad, 0.0]])
        K.forward_batch(
            model.packed,
            model.flags,
            state[0],
            state[1],
            v,
            state[3],
            np.full((1, 6), 180.0),
            np.zeros((1, 6)),
            out[b : b + 1],
        )
    # the kernels' floating-point licence assumes nothing about finiteness (no -ffast-math, cpp/CMakeLists.txt)
    assert not np.isfinite(out).all(axis=1).any()


def test_arguments_of_any_layout_and_number_type_give_the_same_result(dasgupta, rng):
    model = se.make_dynamics("improved", dasgupta)
    t, R, v, w = random_state(dasgupta, rng)
    F = (rng.normal(size=6) * 300).astype(np.float32)
    want = np.concatenate(model.forward(t, R, v, w, F.astype(np.float64)))
    wide = np.zeros((3, 6))
    wide[:, 2] = t  # a strided column
    got = model.forward(wide[:, 2], np.asfortranarray(R), list(v), tuple(w), F)
    assert np.array_equal(np.concatenate(got), want)
    assert np.array_equal(
        np.concatenate(model.forward(t, R, v, w, np.round(F).astype(int))),
        np.concatenate(model.forward(t, R, v, w, np.round(F))),
    )


def test_a_pickled_model_keeps_its_rows_and_stays_read_only(dasgupta):
    import pickle

    model = se.make_dynamics("improved+c1", [dasgupta, dasgupta])
    copy = pickle.loads(pickle.dumps(model))
    assert copy.name == model.name and copy.flags == model.flags and copy.params == model.params
    assert np.array_equal(copy.packed, model.packed) and not copy.packed.flags.writeable


def _one_masked(a, index=0):
    """``a`` as a masked array whose entry ``index`` (flat) is masked."""
    a = np.asarray(a, dtype=np.float64)
    return np.ma.masked_array(a, mask=np.arange(a.size).reshape(a.shape) == index)


@pytest.mark.parametrize("entry", list(_entry_points(None, None)))
def test_every_entry_point_refuses_none_and_masked_arrays_naming_the_argument(dasgupta, entry):
    call = _entry_points(se.make_dynamics("improved", dasgupta), dasgupta)[entry]
    t, R, v = dasgupta.home_position, se.rpy_to_matrix([0.02, -0.03, 0.05]), np.zeros(3)
    with pytest.raises(ValueError, match=r"^position: expected an array of numbers of shape \(3,\), got None$"):
        call(None, R, v)
    with pytest.raises(ValueError, match=r"^rotation: expected an array of numbers of shape \(3, 3\), got None$"):
        call(t, None, v)
    with pytest.raises(ValueError, match=r"^position: a masked array with 1 masked value\(s\)"):
        call(_one_masked(t), R, v)
    with pytest.raises(ValueError, match=r"^rotation: a masked array with 1 masked value\(s\)"):
        call(t, _one_masked(R, 4), v)
    call(np.ma.masked_array(t), np.ma.masked_array(R), v)  # nothing masked: the numbers are data


def test_forward_and_inverse_refuse_none_and_masked_arrays_naming_the_argument(dasgupta):
    model = se.make_dynamics("improved", dasgupta)
    t, R, z, F = dasgupta.home_position, np.eye(3), np.zeros(3), np.full(6, 180.0)
    for name, call in {
        "leg_forces": lambda x: model.forward(t, R, z, z, x if x is None else _one_masked(F, 2)),
        "velocity": lambda x: model.forward(t, R, x if x is None else _one_masked(z), z, F),
        "external_wrench": lambda x: model.forward(t, R, z, z, F, x if x is None else _one_masked(np.zeros(6))),
        "lin_acc": lambda x: model.inverse(t, R, z, z, x if x is None else _one_masked(z), z),
        "ang_acc": lambda x: model.inverse(t, R, z, z, z, x if x is None else _one_masked(z, 1)),
        "angular_velocity": lambda x: model.mass_and_bias(t, R, z, x if x is None else _one_masked(z)),
    }.items():
        # the masked entry holds a finite number, which a call reading the buffer would use
        with pytest.raises(ValueError, match=rf"^{name}: a masked array with 1 masked value\(s\); give plain numbers"):
            call("masked")
        if name != "external_wrench":  # None is no wrench
            with pytest.raises(
                ValueError,
                match=rf"^{name}: expected an array of numbers of shape \(\d(, \d)?,?\), "
                "got None$",
            ):
                call(None)
    # a masked array with nothing masked is its numbers
    assert np.array_equal(
        np.hstack(model.forward(t, R, z, z, np.ma.masked_array(F))), np.hstack(model.forward(t, R, z, z, F))
    )
    assert np.array_equal(model.inverse(t, R, z, z, np.ma.masked_array(z), z), model.inverse(t, R, z, z, z, z))


def test_model_calls_refuse_none_and_masked_arrays_naming_the_argument(dasgupta):
    model = se.make_dynamics("improved", [dasgupta, dasgupta])
    for call, message in [
        (lambda: se.make_dynamics("improved", None), r"^params: expected a PlatformParams or a non-empty sequence"),
        (lambda: model.with_params(None), r"^params: expected a PlatformParams or a non-empty sequence"),
        (lambda: model.with_rows(None, [dasgupta]), r"^rows: expected a sequence of integer batch rows, got NoneType"),
        (lambda: model.with_rows([0], None), r"^params: expected a sequence of PlatformParams"),
        (lambda: model.with_rows([0], [None]), r"^params: expected PlatformParams, got NoneType"),
        (lambda: model.with_packed_rows([0], None, [dasgupta]), r"^packed_rows: expected an array of shape"),
        (
            lambda: model.with_packed_rows([0], _one_masked(model.packed[:1], 5), [dasgupta]),
            r"^packed_rows: a masked array with 1 masked value\(s\)",
        ),
        (lambda: model.with_packed_rows([0], model.packed[:1], None), r"^sources: expected a sequence"),
        (lambda: model.params_of(None), r"^row: expected an integer in \[0, 1\], got None"),
        (lambda: se.dynamics.pack_params(None), r"^params: expected a PlatformParams"),
    ]:
        with pytest.raises(ValueError, match=message):
            call()
