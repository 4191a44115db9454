"""Tests of the constraints (stewart_env/tasks/constraints.py and the compiled evaluation,
stewart_env/_core/cpp/tasks/constraints.hpp): hand-computed values, a numpy reference, the
indicator costs of crafted violations, batch-size invariance and hostile input."""

import dataclasses
import importlib
import math
import pickle

import numpy as np
import pytest

from stewart_env import _core
from stewart_env._core import _cpu_features
from stewart_env.errors import UsageError
from stewart_env.params import load_platform
from stewart_env.rotations import matrix_to_rpy, rpy_to_matrix
from stewart_env.state import PlatformState
from stewart_env.tasks.constraints import CONSTRAINT_NAMES, DEFAULT_TERMINATE_ON, Constraints

DT = 0.01
K = {name: k for k, name in enumerate(CONSTRAINT_NAMES)}


def states(position, rotation, velocity=(0.0, 0.0, 0.0), angular_velocity=(0.0, 0.0, 0.0)) -> PlatformState:
    """A batch of one state (arrays of (1, ...))."""
    return PlatformState(
        np.array([position], dtype=float),
        np.array([rotation], dtype=float),
        np.array([velocity], dtype=float),
        np.array([angular_velocity], dtype=float),
    )


def evaluate(constraints, state, previous_rates=None, previous_forces=None, forces=None):
    """The arrays of one evaluation, zero rates and forces where not given."""
    n = state.position.shape[0]
    zeros = np.zeros((n, 6))
    out = constraints.arrays(n)
    constraints.evaluate(
        state,
        zeros if previous_rates is None else previous_rates,
        zeros if previous_forces is None else previous_forces,
        zeros if forces is None else forces,
        out,
    )
    return out


def reference(params, state, previous_rates, previous_forces, forces, dt):
    """Values and margins (n, 8, 6) by numpy, from docs/physics.md's eqs. L1-L5."""
    lim = params.limits
    t, R, v, w = state
    q = np.einsum("nij,kj->nki", R, params.platform_joints)
    legs = t[:, None] + q - params.base_joints
    L = np.linalg.norm(legs, axis=2)
    e = legs / L[..., None]
    rates = np.einsum("nki,ni->nk", e, v) + np.einsum("nki,ni->nk", np.cross(q, e), w)
    accelerations = (rates - previous_rates) / dt
    force_rates = (forces - previous_forces) / dt

    def cone(axes, e):
        return np.arctan2(np.linalg.norm(np.cross(axes, e), axis=-1), np.sum(axes * e, axis=-1))

    universal = cone(lim.universal_axes[None], e)
    spherical = cone(np.einsum("nij,kj->nki", R, lim.spherical_axes), e)
    rpy = np.array([matrix_to_rpy(r) for r in R])
    angles = (rpy - params.home_rpy + np.pi) % (2 * np.pi) - np.pi
    values = np.stack([L, rates, accelerations, forces, force_rates, universal, spherical, np.hstack([t, angles])], 1)

    def within(x, lo, hi):
        return np.minimum(x - lo, hi - x)

    def below(x, bound):
        return np.full_like(x, np.inf) if bound == np.inf else bound - np.abs(x)

    margins = np.stack(
        [
            within(L, *lim.leg_length),
            below(rates, lim.max_leg_velocity),
            below(accelerations, lim.max_leg_acceleration),
            within(forces, *lim.leg_force),
            below(force_rates, lim.max_force_rate),
            below(universal, lim.max_universal_angle),
            below(spherical, lim.max_spherical_angle),
            np.hstack([within(t, lim.position_min, lim.position_max), below(angles, lim.max_angle)]),
        ],
        1,
    )
    return values, margins


def random_batch(params, rng, n):
    """n states around home (inside and outside the limits), the previous rates and forces, the forces."""
    lim = params.limits
    half = 0.6 * (lim.position_max - lim.position_min)
    centre = 0.5 * (lim.position_max + lim.position_min)
    t = centre + rng.uniform(-half, half, (n, 3))
    R = np.array([rpy_to_matrix(r) for r in params.home_rpy + rng.uniform(-1.2, 1.2, (n, 3)) * lim.max_angle])
    v = rng.normal(scale=0.6, size=(n, 3))
    w = rng.normal(scale=0.6, size=(n, 3))
    span = lim.leg_force[1] - lim.leg_force[0]
    forces = rng.uniform(lim.leg_force[0] - 0.1 * span, lim.leg_force[1] + 0.1 * span, (n, 6))
    previous_forces = forces + rng.normal(scale=0.01 * span, size=(n, 6))
    previous_rates = rng.normal(scale=0.6, size=(n, 6))
    return PlatformState(t, R, v, w), previous_rates, previous_forces, forces


@pytest.fixture(scope="module")
def simulator_constraints(simulator):
    return Constraints(simulator, DT, terminate_on=CONSTRAINT_NAMES)


# ----------------------------------------------------------------------------------------------
# Hand cases.


def test_heave_velocity_gives_each_leg_e_dot_v(dasgupta):
    # The default platform at home (P at [0, 0, 0.4]): leg i runs from b_i to P + p_i, which lie
    # 0.6 m apart in z (b_i at z = -0.6, p_i at z = -0.4 in {P}). Its squared lengths from the
    # config's x, y: leg 0: 0.79^2 + 0.779^2 + 0.6^2 = 1.590941; leg 1: 0.28^2 + 1.074^2 + 0.36 =
    # 1.591876; leg 4: 1.07^2 + 0.295^2 + 0.36 = 1.591925; legs 2, 3, 5 mirror 1, 0, 4. A heave
    # velocity v = [0, 0, vz] gives Ldot_i = e_i . v = 0.6 vz / L_i.
    squared = np.array([1.590941, 1.591876, 1.591876, 1.590941, 1.591925, 1.591925])
    vz = 0.25
    out = evaluate(Constraints(dasgupta, DT), states([0.0, 0.0, 0.4], np.eye(3), [0.0, 0.0, vz]))
    # rounding: a few ulps of the leg vector's sums and square root
    np.testing.assert_allclose(out.values[0, K["leg_length"]], np.sqrt(squared), rtol=1e-15)
    np.testing.assert_allclose(out.values[0, K["leg_velocity"]], 0.6 * vz / np.sqrt(squared), rtol=1e-14)
    assert out.values[0, K["leg_velocity"], 0] == pytest.approx(0.1189226, abs=1e-7)
    # the previous rates were zero: the step's mean acceleration is Ldot / dt
    np.testing.assert_allclose(out.values[0, K["leg_acceleration"]], 0.6 * vz / np.sqrt(squared) / DT, rtol=1e-14)


def test_cone_angles_at_known_angles(dasgupta):
    # At home the legs lean arccos(0.6 / L_i) from the vertical, the base's and the level
    # platform's z axes: 61.6 deg (the config's "about 62 deg").
    squared = np.array([1.590941, 1.591876, 1.591876, 1.590941, 1.591925, 1.591925])
    e = (dasgupta.home_position + dasgupta.platform_joints - dasgupta.base_joints) / np.sqrt(squared)[:, None]
    # Spherical mounting axes tilted from each home leg by a known angle, about e_i x z.
    tilt = np.array([0.1, 0.2, 0.3, 0.5, 0.8, 1.3])
    normal = np.cross(np.cross(e, [0.0, 0.0, 1.0]), e)
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    axes = np.cos(tilt)[:, None] * e + np.sin(tilt)[:, None] * normal
    params = dasgupta.replace(limits=dataclasses.replace(dasgupta.limits, spherical_axes=axes))
    out = evaluate(Constraints(params, DT), states([0.0, 0.0, 0.4], np.eye(3)))
    # rounding: atan2 of products of unit vectors, a few ulps
    np.testing.assert_allclose(out.values[0, K["universal_joint"]], np.arccos(0.6 / np.sqrt(squared)), rtol=1e-14)
    assert math.degrees(out.values[0, K["universal_joint"], 0]) == pytest.approx(61.60, abs=0.01)
    np.testing.assert_allclose(out.values[0, K["spherical_joint"]], tilt, rtol=1e-14)


# ----------------------------------------------------------------------------------------------
# The compiled evaluation against numpy.


@pytest.mark.parametrize("platform", ["dasgupta1998", "motion_simulator"])
def test_compiled_equals_numpy_reference(platform, rng):
    params = load_platform(platform)
    constraints = Constraints(params, DT, terminate_on=())
    batch = random_batch(params, rng, 200)
    out = evaluate(constraints, *batch)
    values, margins = reference(params, *batch, DT)
    scale = np.abs(values).max(axis=(0, 2), keepdims=True)
    # rounding: the two compute the same sums in other orders; relative to each quantity's scale
    assert (np.abs(out.values - values) <= 1e-12 * scale).all()
    finite = np.isfinite(margins)
    np.testing.assert_array_equal(np.isfinite(out.margins), finite)
    difference = np.abs(out.margins[finite] - margins[finite])
    assert (difference <= 1e-12 * np.broadcast_to(scale, margins.shape)[finite]).all()
    violated = (margins < 0).any(axis=2)
    np.testing.assert_array_equal(out.violated, violated)
    np.testing.assert_array_equal(out.costs, violated.astype(float))
    np.testing.assert_array_equal(out.cost, violated.sum(axis=1))
    assert 0 < out.cost.mean() < len(constraints.names)  # the batch holds violations and rows inside
    np.testing.assert_array_equal(out.code, 0)


def test_workspace_and_stroke_as_the_task_kernels_decide(simulator, rng):
    constraints = Constraints(simulator, DT)
    state, *rest = random_batch(simulator, rng, 500)
    out = evaluate(constraints, state, *rest)
    lim = simulator.limits
    lengths, condition = np.empty((500, 6)), np.zeros(500)
    lengths[:] = out.values[:, K["leg_length"]]
    code = np.empty(500, dtype=np.int64)
    _core.limit_codes(
        state.position, state.rotation, lengths, condition, np.zeros(500, dtype=bool), lim.position_min,
        lim.position_max, simulator.home_rpy, lim.max_angle, lim.leg_length[0], lim.leg_length[1],
        lim.max_condition, code,
    )  # fmt: skip
    np.testing.assert_array_equal(out.violated[:, K["leg_length"]], code == 3)
    inside_stroke = code != 3
    np.testing.assert_array_equal(out.violated[inside_stroke, K["workspace"]], code[inside_stroke] == 4)
    assert 0 < (code == 3).sum() < 500 and 0 < (code == 4).sum() < 500


def test_batch_rows_equal_batches_of_one(simulator_constraints, simulator, rng):
    batch = random_batch(simulator, rng, 64)
    whole = evaluate(simulator_constraints, *batch)
    for r in range(64):
        row = evaluate(
            simulator_constraints,
            PlatformState(*(a[r : r + 1] for a in batch[0])),
            *(a[r : r + 1] for a in batch[1:]),
        )
        for got, expected in zip(row, whole):
            np.testing.assert_array_equal(got[0], expected[r])


# ----------------------------------------------------------------------------------------------
# Indicator costs.


def holding(simulator):
    """The simulator at rest at home, every leg holding 1.6e4 N since the previous step."""
    forces = np.full((1, 6), 1.6e4)
    return states(simulator.home_position, np.eye(3)), np.zeros((1, 6)), forces, forces.copy()


def test_no_cost_inside_every_limit(simulator_constraints, simulator):
    out = evaluate(simulator_constraints, *holding(simulator))
    assert out.cost[0] == 0.0 and not out.violated.any() and out.code[0] == 0
    assert (out.margins > 0).all()
    info = simulator_constraints.info(out, 0)
    assert info == {"cost": 0.0, **{f"cost_{name}": 0.0 for name in CONSTRAINT_NAMES}}


def _violations(simulator):
    """Each constraint's crafted violation: (name, params, state, previous_rates, previous_forces, forces)."""
    home, rates, forces, _ = holding(simulator)
    lim = simulator.limits
    at = simulator.home_position
    e_z = 0.878105  # the legs' vertical component at home (the config's axes)
    cases = {
        # a stroke ending 1 cm above the home length (2.9609 m); 5 cm of heave lengthens legs ~4 cm
        "leg_length": (dataclasses.replace(lim, leg_length=(2.0, 2.97)), states(at + [0, 0, 0.05], np.eye(3))),
        # 1 m/s of heave: Ldot = 0.878 m/s > 0.8, the previous rates the same (no acceleration)
        "leg_velocity": (lim, states(at, np.eye(3), [0.0, 0.0, 1.0]), np.full((1, 6), e_z)),
        # 0.5 m/s of heave reached from rest in one 10 ms step: 43.9 m/s^2 > 8
        "leg_acceleration": (lim, states(at, np.eye(3), [0.0, 0.0, 0.5]), np.zeros((1, 6))),
        # 1.3e5 N held > 1.2e5 N
        "leg_force": (lim, home, rates, np.full((1, 6), 1.3e5), np.full((1, 6), 1.3e5)),
        # 3e4 N more than the previous step's within 10 ms: 3e6 N/s > 2e6
        "force_rate": (lim, home, rates, forces, forces + 3e4),
        # 0.3 m of sway leans the legs up to about 6 deg from home: above a 0.05 rad universal cone
        "universal_joint": (
            dataclasses.replace(lim, max_universal_angle=0.05, max_spherical_angle=math.inf),
            states(at + [0.3, 0, 0], np.eye(3)),
        ),
        "spherical_joint": (
            dataclasses.replace(lim, max_spherical_angle=0.05, max_universal_angle=math.inf),
            states(at + [0.3, 0, 0], np.eye(3)),
        ),
        # 0.45 rad of yaw, beyond the workspace's 0.4 rad (the cones stay inside)
        "workspace": (lim, states(at, rpy_to_matrix([0.0, 0.0, 0.45]))),
    }
    for name, (limits, state, *arrays) in cases.items():
        if len(arrays) == 1:  # previous rates given: forces held
            arrays = [arrays[0], forces, forces]
        elif not arrays:
            arrays = [rates, forces, forces]
        yield name, simulator.replace(limits=limits), state, *arrays


@pytest.mark.parametrize("case", list(_violations(load_platform("motion_simulator"))), ids=lambda c: c[0])
def test_each_crafted_violation_costs_one(case):
    name, params, state, previous_rates, previous_forces, forces = case
    constraints = Constraints(params, DT, terminate_on=(name,))
    out = evaluate(constraints, state, previous_rates, previous_forces, forces)
    expected = np.zeros(len(CONSTRAINT_NAMES))
    expected[K[name]] = 1.0
    np.testing.assert_array_equal(out.costs[0], expected)
    assert out.cost[0] == 1.0
    assert out.code[0] == K[name] + 1 and constraints.termination_reason(int(out.code[0])) == name
    assert out.margins[0, K[name]].min() < 0
    info = constraints.info(out, 0)
    assert info["cost"] == 1.0 and info[f"cost_{name}"] == 1.0
    # not among the constraints that end an episode: a cost, no termination
    assert (
        evaluate(Constraints(params, DT, terminate_on=()), state, previous_rates, previous_forces, forces).code[0] == 0
    )


def test_codes_name_the_first_terminating_violation(simulator):
    # Leg force and workspace violated together: the code names the first of terminate_on's that is.
    state = states(simulator.home_position, rpy_to_matrix([0.0, 0.0, 0.45]))
    big = np.full((1, 6), 1.3e5)
    default = evaluate(Constraints(simulator, DT), state, None, big, big)
    assert Constraints(simulator, DT).terminate_on == DEFAULT_TERMINATE_ON
    assert default.cost[0] == 2.0 and default.code[0] == K["workspace"] + 1
    both = evaluate(Constraints(simulator, DT, terminate_on=("workspace", "leg_force")), state, None, big, big)
    assert both.code[0] == K["leg_force"] + 1


def test_batch_info_and_the_platform_without_optional_limits(dasgupta, rng):
    constraints = Constraints(dasgupta, DT)
    assert constraints.names == ("leg_length", "leg_force", "workspace")
    out = evaluate(constraints, *random_batch(dasgupta, rng, 50))
    info = constraints.info(out)
    assert tuple(info) == constraints.info_keys == ("cost", "cost_leg_length", "cost_leg_force", "cost_workspace")
    np.testing.assert_array_equal(
        info["cost"], info["cost_leg_length"] + info["cost_leg_force"] + info["cost_workspace"]
    )
    # the absent limits never cost, whatever the rates
    assert not out.violated[:, [K["leg_velocity"], K["leg_acceleration"], K["force_rate"]]].any()
    assert (out.margins[:, K["universal_joint"]] == np.inf).all()
    assert isinstance(constraints.info(out, 3)["cost"], float)


# ----------------------------------------------------------------------------------------------
# Hostile input.


def test_non_finite_values_count_as_violations_never_as_nan_costs(simulator_constraints, simulator, dasgupta):
    nan_state = states([np.nan, 0.0, 2.6], np.eye(3), [np.inf, 0.0, 0.0])
    nan = np.full((1, 6), np.nan)
    out = evaluate(simulator_constraints, nan_state, nan, nan, nan)
    assert not np.isnan(out.costs).any() and not np.isnan(out.cost).any() and not np.isnan(out.margins).any()
    assert out.violated.all() and out.cost[0] == len(CONSTRAINT_NAMES)
    assert out.code[0] == 1  # the first constraint that ends an episode, the stroke
    # NaN leg forces alone: the force and its rate are violated, nothing else
    home, rates, forces, _ = holding(simulator)
    out = evaluate(simulator_constraints, home, rates, forces, nan)
    np.testing.assert_array_equal(np.flatnonzero(out.costs[0]), [K["leg_force"], K["force_rate"]])
    # a constraint the platform does not have is never violated, even by a NaN
    out = evaluate(Constraints(dasgupta, DT), nan_state, nan, nan, nan)
    assert out.cost[0] == 3.0 and np.isposinf(out.margins[0, K["leg_velocity"]]).all()


def test_refuses_wrong_arrays_and_periods(simulator_constraints, simulator):
    home, rates, forces, _ = holding(simulator)
    out = simulator_constraints.arrays(1)
    with pytest.raises(ValueError, match=r"forces \(N, 6\): expected shape \(1, 6\), got \(1, 5\)"):
        simulator_constraints.evaluate(home, rates, forces, forces[:, :5], out)
    with pytest.raises(ValueError, match=r"values \(N, N_CONSTRAINTS, 6\): expected shape \(1, 8, 6\)"):
        simulator_constraints.evaluate(home, rates, forces, forces, simulator_constraints.arrays(2))
    with pytest.raises(ValueError, match=r"control_dt: expected a finite number > 0"):
        _core.evaluate_constraints(
            simulator_constraints.bounds, 0, simulator_constraints.prm, *home, rates, forces, forces, math.nan, *out
        )
    for dt in (0.0, -0.01, math.inf, math.nan):
        with pytest.raises(UsageError) as err:
            Constraints(simulator, dt)
        assert err.value.argument == "control_dt"


@pytest.mark.parametrize(
    ("platform", "terminate_on", "message"),
    [
        ("motion_simulator", ("leg_stroke",), "unknown constraint 'leg_stroke'; choose from leg_length, leg_velocity"),
        (
            "dasgupta1998",
            ("spherical_joint",),
            "unknown constraint 'spherical_joint' ('dasgupta1998' has no spherical_joint limit: "
            "limits.spherical_joint.max_angle is absent); choose from leg_length, leg_force, workspace",
        ),
        ("dasgupta1998", "workspace", "expected a tuple of constraint names, got str"),
        ("dasgupta1998", (3,), "unknown constraint int; choose from"),
    ],
)
def test_terminate_on_lists_the_choices(platform, terminate_on, message):
    with pytest.raises(UsageError) as err:
        Constraints(load_platform(platform), DT, terminate_on=terminate_on)
    assert err.value.argument == "terminate_on"
    assert str(err.value).startswith("terminate_on: " + message)


def test_copies_evaluate_as_the_original(simulator, rng):
    constraints = Constraints(simulator, DT, terminate_on=("leg_velocity", "workspace"))
    copy = pickle.loads(pickle.dumps(constraints))
    assert copy == constraints and copy.terminate_on == ("leg_velocity", "workspace")
    batch = random_batch(simulator, rng, 16)
    for got, expected in zip(evaluate(copy, *batch), evaluate(constraints, *batch)):
        np.testing.assert_array_equal(got, expected)


def test_leg_rates_of_a_start_state(simulator_constraints, simulator):
    state = states(simulator.home_position, np.eye(3), [0.0, 0.0, 0.5])
    # rounding: the axes' six printed digits against the exact home directions
    np.testing.assert_allclose(simulator_constraints.leg_rates(state), 0.5 * 0.878105, rtol=1e-6)


def test_every_instruction_set_target_gives_the_same_numbers(simulator, rng):
    constraints = Constraints(simulator, DT, terminate_on=CONSTRAINT_NAMES)
    batch = random_batch(simulator, rng, 128)
    expected = evaluate(constraints, *batch)
    lim = simulator.limits
    runnable = [t for t in _core._built_targets() if t in _cpu_features.runnable()]
    for target in runnable:
        kernels = importlib.import_module(f"stewart_env._core.{_core._module_name(target)}")
        # each target's extension has its own types: its bounds are built from the same numbers
        bounds = kernels.ConstraintBounds(
            *lim.leg_length, lim.max_leg_velocity, lim.max_leg_acceleration, *lim.leg_force, lim.max_force_rate,
            lim.max_universal_angle, lim.max_spherical_angle, lim.universal_axes, lim.spherical_axes,
            lim.position_min, lim.position_max, simulator.home_rpy, lim.max_angle,
        )  # fmt: skip
        out = constraints.arrays(128)
        state, *rest = batch
        kernels.evaluate_constraints(bounds, 255, constraints.prm, *state, *rest, DT, *out)
        for got, want in zip(out, expected):
            np.testing.assert_array_equal(got, want)
