"""The study's workers size the physics threads to the CPUs they were given: jobs side by side on
one machine share its cores instead of each taking all of them."""

from __future__ import annotations

import pytest

import stewart_env as se
from stewart_env.agents.studies.mismatch.constants import CPUS_PER_JOB
from stewart_env.agents.studies.mismatch.jobs import on_threads


@pytest.fixture
def restore_threads():
    before = se.get_num_threads()
    yield
    se.set_num_threads(before)


def test_a_job_runs_on_the_threads_it_is_given(restore_threads):
    se.set_num_threads(3)
    assert on_threads(1, lambda a, b: (a + b, se.get_num_threads()), 2, 5) == (7, 1)
    assert on_threads(2, se.get_num_threads) == 2


@pytest.mark.slow  # a local Ray instance starts in about 5-10 s
@pytest.mark.extra("distributed")
def test_a_ray_worker_uses_as_many_physics_threads_as_it_has_cpus():
    import ray

    from stewart_env.agents.studies.mismatch import RayBackend

    # the workers' environment asks for 3 threads: the job's CPUs must win over it
    ray.init(
        num_cpus=2,
        include_dashboard=False,
        logging_level="ERROR",
        log_to_driver=False,
        runtime_env={"env_vars": {"STEWART_ENV_THREADS": "3"}},
    )
    try:
        backend = RayBackend()
        counts = [count for _, count in backend.run(se.get_num_threads, [(), (), ()])]
    finally:
        ray.shutdown()
    assert counts == [CPUS_PER_JOB] * 3
