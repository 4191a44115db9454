"""Tests of the action delay's ring buffer (stewart_env/envs/action_delay.py): its exact semantics,
per-row starts, copies and its refusals."""

import copy
import pickle

import numpy as np
import pytest

from stewart_env.envs.action_delay import MAX_DELAY_STEPS, ActionDelay
from stewart_env.errors import UsageError


def actions(steps: int, n: int = 3, dim: int = 6) -> np.ndarray:
    """Distinct actions: entry (step, row, j) = step + row / 10 + j / 100, so a wrong slot, row or
    leg shows in the value."""
    step, row, j = np.meshgrid(np.arange(steps), np.arange(n), np.arange(dim), indexing="ij")
    return step + row / 10 + j / 100


def test_delay_zero_is_the_identity():
    delay = ActionDelay(3, 0)
    for action in actions(5):
        np.testing.assert_array_equal(delay.push(action), action)
    assert delay.pending().shape == (0, 3, 6)


@pytest.mark.parametrize("delay_steps", [1, 2, 5])
def test_push_gives_back_the_action_of_delay_steps_ago(delay_steps):
    delay = ActionDelay(3, delay_steps)
    given = actions(12)
    got = np.array([delay.push(a).copy() for a in given])
    # The first delay_steps pushes give back the start action (zeros), then the inputs, shifted.
    np.testing.assert_array_equal(got[:delay_steps], 0.0)
    np.testing.assert_array_equal(got[delay_steps:], given[:-delay_steps])


def test_pinned_sequence_of_one_row():
    delay = ActionDelay(1, 2, dim=1)
    got = [float(delay.push(np.array([[a]]))[0, 0]) for a in (1.0, 2.0, 3.0, 4.0, 5.0)]
    assert got == [0.0, 0.0, 1.0, 2.0, 3.0]
    np.testing.assert_array_equal(delay.pending()[:, 0, 0], [4.0, 5.0])


def test_reset_rows_starts_some_rows_with_their_action():
    delay = ActionDelay(3, 2)
    given = actions(6)
    for a in given[:3]:
        delay.push(a)
    start = np.full(6, -0.5)
    delay.reset_rows(np.array([1]), start)
    out = [delay.push(a).copy() for a in given[3:]]
    # Row 1 gives back its start action for two steps, then its own new actions; rows 0 and 2 go on.
    np.testing.assert_array_equal(out[0][1], start)
    np.testing.assert_array_equal(out[1][1], start)
    np.testing.assert_array_equal(out[2][1], given[3][1])
    for k in range(3):
        np.testing.assert_array_equal(out[k][[0, 2]], given[1 + k][[0, 2]])


def test_reset_rows_by_mask_and_per_row_actions():
    delay = ActionDelay(3, 1)
    delay.push(actions(1)[0])
    per_row = np.array([[1.0] * 6, [2.0] * 6])
    delay.reset_rows(np.array([True, False, True]), per_row)
    out = delay.push(np.zeros((3, 6)))
    np.testing.assert_array_equal(out[[0, 2]], per_row)
    np.testing.assert_array_equal(out[1], actions(1)[0][1])
    delay.reset_rows()  # every row, zeros
    np.testing.assert_array_equal(delay.push(np.ones((3, 6))), 0.0)


def test_copies_go_on_as_the_original():
    delay = ActionDelay(3, 3)
    given = actions(8)
    for a in given[:4]:
        delay.push(a)
    pickled = pickle.loads(pickle.dumps(delay))
    deep = copy.deepcopy(delay)
    for a in given[4:]:
        expected = delay.push(a).copy()
        np.testing.assert_array_equal(pickled.push(a), expected)
        np.testing.assert_array_equal(deep.push(a), expected)
    # a copy is independent: pushing into it leaves the original's ring alone
    before = delay.pending()
    deep.push(np.full((3, 6), 9.0))
    np.testing.assert_array_equal(delay.pending(), before)


@pytest.mark.parametrize(
    ("kwargs", "argument"),
    [
        ({"n": 2, "delay_steps": -1}, "delay_steps"),
        ({"n": 2, "delay_steps": MAX_DELAY_STEPS + 1}, "delay_steps"),
        ({"n": 0, "delay_steps": 1}, "n"),
        ({"n": 2, "delay_steps": 1, "dim": 0}, "dim"),
        ({"n": 2, "delay_steps": True}, "delay_steps"),
        ({"n": 2, "delay_steps": 1.5}, "delay_steps"),
    ],
)
def test_refuses_arguments_out_of_range(kwargs, argument):
    with pytest.raises(UsageError) as err:
        ActionDelay(**kwargs)
    assert err.value.argument == argument
    assert str(err.value).startswith(f"{argument}: ")


def test_refuses_actions_of_another_shape():
    delay = ActionDelay(2, 1)
    with pytest.raises(ValueError, match=r"^action: expected shape \(2, 6\), got \(6,\)"):
        delay.push(np.zeros(6))
    with pytest.raises(ValueError, match=r"^action: expected shape \(6,\) or \(1, 6\), got \(2, 6\)"):
        delay.reset_rows(np.array([0]), np.zeros((2, 6)))
