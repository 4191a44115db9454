"""The cueing task's schedule: given (motion, seed) pairs, one per row reset, in order, then draws again."""

from __future__ import annotations

import numpy as np
import pytest

from stewart_env.envs.vector import StewartPlatformVectorEnv
from stewart_env.errors import UsageError
from stewart_env.tasks.cueing.motions import EVALUATION_SEEDS

pytestmark = pytest.mark.env

NAMES = ("braking", "slalom", "coordinated_turn")


def make(n: int) -> StewartPlatformVectorEnv:
    return StewartPlatformVectorEnv(num_envs=n, task="cueing", action_mode="pose", task_options={"motions": NAMES})


def test_scheduled_episodes_go_to_the_rows_in_order_and_the_draws_resume():
    env = make(3)
    pairs = [("slalom", 5), ("braking", int(EVALUATION_SEEDS[1])), ("slalom", 7)]
    env.task.schedule(pairs)
    env.reset(seed=0)
    episode = env._core.episode
    assert episode["motion"].tolist() == [1.0, 0.0, 1.0]
    assert episode["seed"].tolist() == [5.0, float(EVALUATION_SEEDS[1]), 7.0]
    # the observed vehicle signal is the scheduled motion's first sample
    part = env.decode_observation(env._core.observation)
    first = env.task.motion_of(0, int(EVALUATION_SEEDS[1]))[0]
    np.testing.assert_allclose(part["vehicle_specific_force"][1], first[:3], rtol=1e-6)  # float32 observations
    # used up: the next reset draws from the rows' generators, as without a schedule
    env.reset(seed=0)
    drawn = env._core.episode["seed"].copy()
    fresh = make(3)
    fresh.reset(seed=0)
    assert drawn.tolist() == fresh._core.episode["seed"].tolist()
    env.close()
    fresh.close()


def test_a_bad_schedule_is_named():
    env = make(1)
    with pytest.raises(UsageError, match=r"episodes: entry 0 must be a \(motion, seed\) pair with a motion of braking"):
        env.task.schedule([("turbulence", 0)])
    with pytest.raises(UsageError, match=r"episodes\[0\] seed"):
        env.task.schedule([("braking", -1)])
    env.close()
