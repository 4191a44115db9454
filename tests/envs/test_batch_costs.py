"""Tests of the batch's constraint costs (stewart_env/envs/costs.py, BatchCosts) against the full
evaluation (Constraints.evaluate): the one compiled call a step (_core.constraint_costs) gives the
same costs bit for bit, keeps the leg rates and forces for the next step in place, and ends the
rows of the added constraints as the evaluation's violations say."""

import numpy as np
import pytest

from stewart_env import _core
from stewart_env.envs.costs import BatchCosts
from stewart_env.rotations import rpy_to_matrix
from stewart_env.state import PlatformState
from stewart_env.tasks.constraints import CONSTRAINT_NAMES, Constraints

DT = 0.01
LEG_VELOCITY = CONSTRAINT_NAMES.index("leg_velocity")


def random_batch(params, rng, n):
    """n states about home, inside and outside every limit, with a row of no numbers; the forces."""
    lim = params.limits
    half = 0.6 * (lim.position_max - lim.position_min)
    centre = 0.5 * (lim.position_max + lim.position_min)
    t = centre + rng.uniform(-half, half, (n, 3))
    R = np.array([rpy_to_matrix(r) for r in params.home_rpy + rng.uniform(-1.2, 1.2, (n, 3)) * lim.max_angle])
    v = rng.normal(scale=0.6, size=(n, 3))
    w = rng.normal(scale=0.6, size=(n, 3))
    t[1] = np.nan  # a state that is none costs every constraint it reaches
    span = lim.leg_force[1] - lim.leg_force[0]
    forces = rng.uniform(lim.leg_force[0] - 0.1 * span, lim.leg_force[1] + 0.1 * span, (n, 6))
    return PlatformState(t, R, v, w), forces


def full_evaluation(constraints, state, rates, forces_before, forces, fresh):
    """Constraints.evaluate as the batch did it: a fresh row's previous forces are its forces."""
    forces_before = np.where(fresh[:, None], forces, forces_before)
    out = constraints.arrays(len(forces))
    return constraints.evaluate(state, rates, forces_before, forces, out)


@pytest.mark.parametrize("platform", ["simulator", "dasgupta"])
@pytest.mark.parametrize(
    "terminate_on", [("leg_length", "workspace"), ("leg_velocity", "force_rate", "leg_force"), ()], ids=str
)
def test_a_step_costs_as_the_full_evaluation_bit_for_bit(platform, terminate_on, rng, request):
    params = request.getfixturevalue(platform)
    terminate_on = tuple(name for name in terminate_on if name in Constraints(params, DT).names)
    n = 200
    costs = BatchCosts(params, DT, n, terminate_on)
    costs.set_first_code(5)
    task_ended = rng.random(n) < 0.2
    for step in range(3):  # the first steps of fresh rows, then steps within their episodes
        state, forces = random_batch(params, rng, n)
        if step == 0:
            costs.reset_rows(np.arange(n), random_batch(params, rng, n)[0])
        elif step == 2:
            again = np.arange(0, n, 3)  # some rows start again
            costs.reset_rows(again, PlatformState(*(x[again] for x in state)))
        rates, forces_before, fresh = costs.previous_rates.copy(), costs.previous_forces.copy(), costs._fresh.copy()
        expected = full_evaluation(costs.constraints, state, rates, forces_before, forces, fresh)
        code = np.where(task_ended, 1, 0).astype(np.int64)
        terms = {"termination": np.zeros(n), "tracking": rng.normal(size=n)}
        tracking = terms["tracking"].copy()
        reward = terms["tracking"].copy()
        costs.after_step(state, forces, code, terms, reward, 10.0)
        np.testing.assert_array_equal(costs.out.costs, expected.costs)
        np.testing.assert_array_equal(costs.out.violated, expected.violated)
        np.testing.assert_array_equal(costs.out.cost, expected.cost)
        np.testing.assert_array_equal(costs.previous_rates, expected.values[:, LEG_VELOCITY])
        np.testing.assert_array_equal(costs.previous_forces, forces)
        assert not costs._fresh.any()
        # the added constraints end the rows that the task did not, each with its first violation
        added = [CONSTRAINT_NAMES.index(name) for name in costs.added_reasons]
        violated = expected.violated[:, added]
        ends = ~task_ended & violated.any(axis=1)
        expected_code = np.where(task_ended, 1, 0)
        if ends.any():
            expected_code[ends] = 5 + np.argmax(violated[ends], axis=1)
        np.testing.assert_array_equal(code, expected_code)
        np.testing.assert_array_equal(terms["termination"], np.where(ends, -10.0, 0.0))
        np.testing.assert_array_equal(reward, np.where(ends, tracking - 10.0, tracking))
        if len(added) and step == 0:
            assert ends.any()  # the random states violate the added constraints in some rows


def test_reset_rows_write_the_start_rates_into_their_rows_only(simulator, rng):
    costs = BatchCosts(simulator, DT, 6, ())
    costs.previous_rates[:] = 7.0
    rows = np.array([4, 1])
    state, _ = random_batch(simulator, rng, 2)
    state = PlatformState(state.position + [[0.0, 0.0, 0.0], [0.01, 0.0, 0.0]], *state[1:])
    state.position[1] = simulator.home_position  # no NaN row here
    costs.reset_rows(rows, state)
    np.testing.assert_array_equal(costs.previous_rates[rows], costs.constraints.leg_rates(state))
    np.testing.assert_array_equal(np.delete(costs.previous_rates, rows, axis=0), 7.0)
    assert costs._fresh.tolist() == [False, True, False, False, True, False]


def test_the_compiled_calls_refuse_a_wrong_shape_naming_the_array(simulator):
    c = Constraints(simulator, DT)
    n = 3
    state = [np.zeros((n, 3)), np.tile(np.eye(3), (n, 1, 1)), np.zeros((n, 3)), np.zeros((n, 3))]
    k = len(CONSTRAINT_NAMES)
    arrays = [np.zeros((n, 6)), np.zeros((n, 6)), np.zeros((n, 6)), np.zeros(n, dtype=bool), DT]
    outs = [np.zeros((n, k)), np.zeros((n, k), dtype=bool), np.zeros(n), np.zeros(n, dtype=np.int64)]
    with pytest.raises(ValueError, match="previous_forces"):
        _core.constraint_costs(c.bounds, 0, c.prm, *state, arrays[0], np.zeros((n, 5)), *arrays[2:], *outs)
    with pytest.raises(ValueError, match="fresh"):
        _core.constraint_costs(c.bounds, 0, c.prm, *state, *arrays[:3], np.zeros(n + 1, dtype=bool), DT, *outs)
    with pytest.raises(IndexError, match="rows"):
        _core.constraint_leg_rates(c.prm, *state, np.array([0, 1, 6]), np.zeros((6, 6)))
