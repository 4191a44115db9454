"""SB3's subprocess envs size their workers' physics threads: W workers on C cores run
max(1, C // W) threads each, not a thread per core each."""

from __future__ import annotations

import gymnasium as gym
import pytest

import stewart_env as se
from stewart_env.agents.training import SizedEnvFactory, available_cores, make_subprocess_env, worker_threads
from stewart_env.errors import UsageError
from stewart_env.registration import ENV_ID

pytestmark = pytest.mark.extra("rl")


class ReportsThreads(gym.Wrapper):
    """The environment, with the physics threads its worker process runs when it was made."""

    def __init__(self, env: gym.Env):
        super().__init__(env)
        self.physics_threads = se.get_num_threads()


def reporting_env() -> gym.Env:
    return ReportsThreads(gym.make(ENV_ID))


@pytest.mark.parametrize("workers, cores, threads", [(1, 8, 8), (2, 8, 4), (3, 8, 2), (8, 8, 1), (16, 8, 1), (3, 2, 1)])
def test_each_worker_gets_its_share_of_the_cores(workers, cores, threads):
    assert worker_threads(workers, cores) == threads


def test_a_bad_count_is_refused_by_name():
    with pytest.raises(UsageError, match="^workers: ") as err:
        worker_threads(0, 4)
    assert err.value.argument == "workers"
    with pytest.raises(UsageError, match="^cores: "):
        worker_threads(2, 0)
    with pytest.raises(UsageError, match="^env_fns: "):
        make_subprocess_env([])


def test_the_factory_sets_the_threads_before_it_makes_the_env():
    before = se.get_num_threads()
    try:
        env = SizedEnvFactory(reporting_env, 1)()
        assert env.physics_threads == 1
        env.close()
    finally:
        se.set_num_threads(before)


def test_a_subprocess_env_s_worker_reports_the_sized_count():
    cores = available_cores()
    if cores < 2:
        pytest.skip("one core: every worker runs one thread, sized or not")
    # two workers on these cores: C // 2 each, where an unsized worker would start one per core (C)
    venv = make_subprocess_env([reporting_env, reporting_env], start_method="spawn")
    try:
        assert venv.get_attr("physics_threads") == [cores // 2, cores // 2]
    finally:
        venv.close()
