"""The constraint costs in the environments' step infos (``cost``, ``cost_<constraint>``), the
constraints that end an episode (``terminate_on=``) and the action delay (``action_delay=``)."""

from __future__ import annotations

import dataclasses
import pickle

import numpy as np
import pytest

from stewart_env.envs import StewartPlatformEnv, StewartPlatformSB3VecEnv, StewartPlatformVectorEnv, holding_action
from stewart_env.envs.costs import BatchCosts
from stewart_env.errors import UsageError
from stewart_env.params import load_platform
from stewart_env.rotations import rpy_to_matrix
from stewart_env.state import PlatformState
from stewart_env.tasks.constraints import CONSTRAINT_NAMES

SIMULATOR = load_platform("motion_simulator")
COST_KEYS = ("cost", *(f"cost_{name}" for name in CONSTRAINT_NAMES))


def with_limits(**changes) -> object:
    """motion_simulator with some of its limits changed."""
    return dataclasses.replace(SIMULATOR, limits=dataclasses.replace(SIMULATOR.limits, **changes))


def costs_of(info) -> dict[str, float]:
    return {key: float(info[key]) for key in info if key.startswith("cost")}


def one_step_from(env, offset=(0.0, 0.0, 0.0), velocity=(0.0, 0.0, 0.0), push=0.0, steps=1):
    """The info of ``steps`` steps from a state set right after reset: home moved by ``offset``
    (m), moving at ``velocity`` (m/s), the action the holding one plus ``push`` on the last step."""
    env.reset(seed=0)
    p = env.unwrapped.platform
    position = p.home_position + np.asarray(offset)
    rotation = rpy_to_matrix(p.home_rpy)
    env.unwrapped.set_state(position, rotation, np.asarray(velocity))
    hold = holding_action(env, position, rotation)
    for k in range(steps):
        action = hold + (push if k == steps - 1 else 0.0)
        info = env.step(action.astype(np.float32))[-1]
    return info


# each case: the platform, env keywords, how the step is made, the one constraint it violates
CASES = {
    # home legs are 2.96 m: lowered 5 cm they are below a stroke that starts at 2.95 m
    "leg_length": (with_limits(leg_length=(2.95, 3.66)), {}, dict(offset=(0.0, 0.0, -0.05))),
    "leg_velocity": (SIMULATOR, {}, dict(velocity=(0.0, 0.0, 0.95))),  # a heave at 0.95 m/s > 0.8
    # 0.3 of the 120 kN range more on each leg: ~27 m/s^2 of heave on the 8 t platform, > 8
    "leg_acceleration": (SIMULATOR, {}, dict(push=0.3)),
    # 3 kN more per leg within 1 ms: 3e6 N/s > 2e6, a heave of ~2 m/s^2 < 8
    "force_rate": (SIMULATOR, dict(control_dt=0.001), dict(push=0.025, steps=2)),
    # 0.3 m sideways tilts the legs ~0.1 rad off their home directions, the joints' axes
    "universal_joint": (with_limits(max_universal_angle=0.05), {}, dict(offset=(0.3, 0.0, 0.0))),
    "spherical_joint": (with_limits(max_spherical_angle=0.05), {}, dict(offset=(0.3, 0.0, 0.0))),
    "workspace": (SIMULATOR, {}, dict(offset=(0.65, 0.0, 0.0))),  # beyond x = 0.6 m
}


@pytest.mark.parametrize("violated", list(CASES))
def test_a_crafted_violation_costs_one_in_its_own_key_only(violated):
    platform, kwargs, step = CASES[violated]
    env = StewartPlatformEnv(platform=platform, terminate_on=(), **kwargs)
    costs = costs_of(one_step_from(env, **step))
    expected = {key: 0.0 for key in COST_KEYS}
    expected["cost"] = expected[f"cost_{violated}"] = 1.0
    assert costs == expected


def test_inside_every_limit_every_cost_is_zero_and_float64():
    env = StewartPlatformEnv(platform="motion_simulator")
    info = one_step_from(env, steps=3)
    assert {key: info[key] for key in COST_KEYS} == dict.fromkeys(COST_KEYS, 0.0)
    assert all(type(info[key]) is np.float64 for key in COST_KEYS)


def test_leg_force_costs_one_for_a_force_outside_the_range():
    # the action map keeps the forces inside the range: the batch's costs are given one outside
    costs = BatchCosts(SIMULATOR, 0.01, 2, ("leg_length", "workspace"))
    home = PlatformState(
        np.tile(SIMULATOR.home_position, (2, 1)),
        np.tile(rpy_to_matrix(SIMULATOR.home_rpy), (2, 1, 1)),
        np.zeros((2, 3)),
        np.zeros((2, 3)),
    )
    rows = np.arange(2)
    costs.reset_rows(rows, home)
    forces = np.zeros((2, 6))
    forces[1, 3] = 121000.0  # > 120 kN; the first step's force rate is 0
    code, terms, reward = np.zeros(2, dtype=np.int64), {"termination": np.zeros(2)}, np.zeros(2)
    costs.after_step(home, forces, code, terms, reward, 10.0)
    info = costs.info()
    assert info["cost"].tolist() == [0.0, 1.0]
    assert info["cost_leg_force"].tolist() == [0.0, 1.0]
    assert sum(info[key][1] for key in info if key != "cost") == 1.0


@pytest.mark.parametrize("platform", ["dasgupta1998", "motion_simulator"])
def test_a_rows_cost_entries_are_the_constraints_own_floats(platform):
    # BatchCosts.info(row) reads the row as one list: the keys, their order and the values must be
    # Constraints.info's of that row, Python floats, for a platform with a subset of the constraints
    params = load_platform(platform)
    costs = BatchCosts(params, 0.01, 3, terminate_on=())
    state = PlatformState(
        np.tile(params.home_position, (3, 1)),
        np.tile(rpy_to_matrix(params.home_rpy), (3, 1, 1)),
        np.zeros((3, 3)),
        np.zeros((3, 3)),
    )
    costs.reset_rows(np.arange(3), state)
    hi = params.limits.leg_force[1]
    forces = np.zeros((3, 6))
    forces[2, 1] = 1.01 * hi  # row 2 outside the force range
    code, terms, reward = np.zeros(3, dtype=np.int64), {"termination": np.zeros(3)}, np.zeros(3)
    costs.after_step(state, forces, code, terms, reward, 10.0)
    for row in range(3):
        entries = costs.info(row)
        expected = costs.constraints.info(costs.out, row)
        assert list(entries) == list(expected) == list(costs.info_keys)
        assert entries == expected
        assert all(type(value) is float for value in entries.values())
    assert costs.info(2)["cost_leg_force"] == 1.0
    assert costs.info(1)["cost"] == 0.0


def test_dasgupta_has_the_three_constraints_of_its_limits():
    env = StewartPlatformEnv()
    env.reset(seed=0)
    info = env.step(np.zeros(6, np.float32))[-1]
    assert [key for key in info if key.startswith("cost")] == [
        "cost",
        "cost_leg_length",
        "cost_leg_force",
        "cost_workspace",
    ]


# -- one step kind as the other, the vector env's rows as single envs -------------------------------


def rollout_costs(env, steps=40, seed=3):
    rng = np.random.default_rng(seed)
    env.reset(seed=seed)
    out = []
    for _ in range(steps):
        *_, terminated, truncated, info = env.step(rng.uniform(-0.4, 0.6, 6).astype(np.float32))
        out.append((costs_of(info), int(info["termination"]), bool(terminated)))
        if terminated:
            env.reset()
    return out


def test_fused_and_parts_give_the_same_costs_and_terminations():
    kwargs = dict(platform="motion_simulator", terminate_on=("leg_velocity", "leg_acceleration"))
    fused, parts = StewartPlatformEnv(**kwargs), StewartPlatformEnv(**kwargs)
    fused.unwrapped._core.set_step_mode("fused")
    parts.unwrapped._core.set_step_mode("parts")
    a, b = rollout_costs(fused), rollout_costs(parts)
    assert a == b
    assert any(c["cost"] > 0 for c, _, _ in a) and any(t for *_, t in a)  # the rollout meets both


def test_vector_rows_give_the_single_envs_costs():
    n, steps = 3, 30
    kwargs = dict(platform="motion_simulator", terminate_on=("leg_length", "leg_velocity", "workspace"))
    venv = StewartPlatformVectorEnv(num_envs=n, **kwargs)
    venv.reset(seed=5)
    rng = np.random.default_rng(0)
    actions = rng.uniform(-0.3, 0.6, (steps, n, 6)).astype(np.float32)
    rows = []
    for k in range(steps):
        *_, infos = venv.step(actions[k])
        rows.append({key: infos[key].copy() for key in COST_KEYS})
    for i in range(n):
        env = StewartPlatformEnv(**kwargs)
        env.reset(seed=5 + i)
        for k in range(steps):
            *_, terminated, truncated, info = env.step(actions[k, i])
            assert {key: info[key] for key in COST_KEYS} == {key: rows[k][key][i] for key in COST_KEYS}
            if terminated:
                break


def test_sb3_rows_carry_the_costs_also_at_an_episode_end():
    venv = StewartPlatformSB3VecEnv(num_envs=2, max_episode_steps=2, platform="motion_simulator")
    venv.seed(0)
    venv.reset()
    for _ in range(2):
        *_, dones, infos = venv.step(np.ones((2, 6), np.float32))
    assert dones.all()
    for info in infos:
        # full force from rest: the legs' acceleration beyond 8 m/s^2, and by now their rate
        assert info["cost_leg_acceleration"] == 1.0 and info["cost"] == sum(info[k] for k in COST_KEYS[1:])


def test_costs_survive_pickling_mid_episode():
    env = StewartPlatformEnv(platform="motion_simulator", terminate_on=("leg_velocity",), action_delay=2)
    env.reset(seed=1)
    for _ in range(3):
        env.step(np.full(6, 0.2, np.float32))
    copy = pickle.loads(pickle.dumps(env))
    for _ in range(5):
        a, b = env.step(np.full(6, 0.3, np.float32)), copy.step(np.full(6, 0.3, np.float32))
        assert costs_of(a[-1]) == costs_of(b[-1]) and a[1] == b[1]


# -- terminate_on ----------------------------------------------------------------------------------


def test_an_added_constraint_ends_the_episode_with_its_reason_and_the_termination_cost():
    step = CASES["leg_velocity"][2]
    ended = StewartPlatformEnv(platform="motion_simulator", terminate_on=("leg_length", "leg_velocity", "workspace"))
    going = StewartPlatformEnv(platform="motion_simulator")
    assert ended.unwrapped.termination_reasons[-1] == "leg_velocity"
    info_end, info_go = one_step_from(ended, **step), one_step_from(going, **step)
    assert ended.unwrapped.termination_reasons[int(info_end["termination"])] == "leg_velocity"
    assert info_go["termination"] == 0
    assert info_end["reward_termination"] == -10.0 and info_go["reward_termination"] == 0.0  # the default cost
    terms = [k for k in info_end if k.startswith("reward_")]
    assert [info_end[k] for k in terms[:-1]] == [info_go[k] for k in terms[:-1]]  # the same step otherwise


def test_terminate_on_pays_the_tasks_own_termination_cost():
    step = CASES["leg_velocity"][2]
    env = StewartPlatformEnv(
        platform="motion_simulator", terminate_on=("leg_velocity",), task_options={"termination_cost": 3.5}
    )
    env.reset(seed=0)
    p = env.unwrapped.platform
    rotation = rpy_to_matrix(p.home_rpy)
    env.unwrapped.set_state(p.home_position, rotation, np.asarray(step["velocity"]))
    _, reward, terminated, _, info = env.step(holding_action(env).astype(np.float32))
    assert terminated and info["reward_termination"] == -3.5
    assert reward == sum(float(info[k]) for k in info if k.startswith("reward_"))


@pytest.mark.parametrize("left_out, offset", [("workspace", (0.65, 0.0, 0.0)), ("leg_length", (0.0, 0.0, -0.05))])
def test_a_limit_left_out_of_terminate_on_no_longer_ends_an_episode(left_out, offset):
    platform = with_limits(leg_length=(2.95, 3.66)) if left_out == "leg_length" else SIMULATOR
    kept = tuple(name for name in ("leg_length", "workspace") if name != left_out)
    default = one_step_from(StewartPlatformEnv(platform=platform), offset=offset)
    env = StewartPlatformEnv(platform=platform, terminate_on=kept)
    info = one_step_from(env, offset=offset)
    reason = {"workspace": "workspace", "leg_length": "leg_stroke"}[left_out]
    assert env.unwrapped.termination_reasons[int(default["termination"])] == reason
    assert info["termination"] == 0 and info[f"cost_{left_out}"] == 1.0


def test_default_terminate_on_is_todays_reasons():
    env = StewartPlatformEnv()
    assert env.unwrapped.termination_reasons == ("", "non_finite", "singularity", "leg_stroke", "workspace")


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(terminate_on=("leg_velocity",)), "terminate_on: unknown constraint 'leg_velocity' ('dasgupta1998' has"),
        (
            dict(terminate_on=("speed",)),
            "terminate_on: unknown constraint 'speed'; choose from leg_length, leg_velocity",
        ),
        (dict(terminate_on="workspace"), "terminate_on: expected a tuple of constraint names, got str"),
        (dict(action_delay=-1), "action_delay"),
        (dict(action_delay=1001), "action_delay"),
        (dict(action_delay=1.5), "action_delay"),
    ],
)
def test_bad_keywords_are_refused_naming_them(kwargs, message):
    with pytest.raises(ValueError) as err:
        StewartPlatformEnv(**kwargs)
    assert str(err.value).startswith(message) or message in str(err.value)
    assert isinstance(err.value, UsageError)


def test_terminate_on_lists_the_platforms_constraints():
    with pytest.raises(UsageError, match=r"choose from leg_length, leg_force, workspace$"):
        StewartPlatformEnv(terminate_on=("force_rate",))


# -- action_delay ----------------------------------------------------------------------------------


@pytest.mark.parametrize("delay", [1, 3])
def test_action_delay_shifts_the_applied_forces_by_exactly_its_steps(delay):
    rng = np.random.default_rng(2)
    actions = rng.uniform(-0.2, 0.2, (12, 6)).astype(np.float32)

    def forces(**kwargs):
        env = StewartPlatformEnv(platform="motion_simulator", terminate_on=(), **kwargs)
        env.reset(seed=0)
        out = []
        for a in actions:
            env.step(a)
            out.append(env.unwrapped.leg_forces.copy())
        return np.array(out)

    now, late = forces(), forces(action_delay=delay)
    np.testing.assert_array_equal(late[delay:], now[:-delay])
    np.testing.assert_array_equal(late[:delay], 0.0)  # the start action, zero: the mid force, 0 N here


def test_action_delay_starts_afresh_at_reset_and_refuses_a_nan_action():
    env = StewartPlatformEnv(action_delay=2)
    env.reset(seed=0)
    env.step(np.ones(6, np.float32))
    env.step(np.ones(6, np.float32))
    with pytest.raises(ValueError, match="action"):
        env.step(np.full(6, np.nan, np.float32))
    env.reset(seed=0)
    env.step(np.ones(6, np.float32))
    np.testing.assert_array_equal(env.unwrapped.leg_forces, 0.0)  # the ones before reset are gone
