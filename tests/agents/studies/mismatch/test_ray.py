"""The mismatch study on Ray: the same matrix as the local backend, and either backend resumes
the other's study."""

from __future__ import annotations

import csv
import shutil

import pytest

ray = pytest.importorskip("ray")

# PPO runs here are a rollout of 2 platforms, smaller than the config's minibatch on purpose.
pytestmark = [
    pytest.mark.filterwarnings("ignore:You have specified a mini-batch size:UserWarning"),
    pytest.mark.slow,
]  # a local Ray instance starts in about 5-10 s, then trains and evaluates

from stewart_env.agents.studies.mismatch import run_mismatch  # noqa: E402

# four tiny agents (the exact model and C2, two seeds each), CT and PD on two models, two plants, 2 episodes of 20 steps
STUDY = dict(
    train_models=["improved"],
    test_models=["classical", "improved"],
    algo="ppo",
    timesteps=100,
    n_envs=2,
    episodes=2,
    seeds=[0, 1],
    simplifications=["c2"],
    max_steps=20,
    progress=False,
)


@pytest.fixture(scope="module")
def local_ray():
    ray.init(num_cpus=2, include_dashboard=False, logging_level="ERROR", log_to_driver=False)
    yield
    ray.shutdown()


def _numbers(path):
    with open(path / "matrix.csv") as f:
        return list(csv.DictReader(f))


def test_ray_and_local_backends_give_the_same_matrix_and_resume_each_other(local_ray, tmp_path):
    on_ray = run_mismatch(tmp_path / "ray", backend="ray", **STUDY)
    local = run_mismatch(tmp_path / "local", backend="local", **STUDY)
    assert [r.label for r in on_ray.rows] == [r.label for r in local.rows]
    # every number equal: the same seeds train the same agents, which run the same episodes
    assert _numbers(tmp_path / "ray") == _numbers(tmp_path / "local")
    assert (tmp_path / "ray" / "differences.csv").read_text() == (tmp_path / "local" / "differences.csv").read_text()

    # a study the Ray backend started, missing one agent and one cell, is finished locally
    shutil.rmtree(tmp_path / "ray" / "agents" / "improved_c2" / "seed_1")
    (tmp_path / "ray" / "cells" / "ct_improved" / "classical" / "model_based.json").unlink()
    kept = tmp_path / "ray" / "cells" / "ppo_improved" / "improved" / "seed_0.json"
    before = kept.stat().st_mtime_ns
    run_mismatch(tmp_path / "ray", backend="local", **STUDY)
    assert kept.stat().st_mtime_ns == before  # finished cells are reused, whoever ran them
    assert (tmp_path / "ray" / "agents" / "improved_c2" / "seed_1" / "model.zip").is_file()
    assert _numbers(tmp_path / "ray") == _numbers(tmp_path / "local")


def test_a_job_error_arrives_as_itself_and_a_dead_worker_as_a_backend_error(local_ray):
    from stewart_env.agents.studies.mismatch import BackendError, RayBackend
    from stewart_env.agents.training import TrainingError

    def refuse():
        raise TrainingError("timesteps: expected a positive integer, got 0")

    def crash():
        import os

        os._exit(1)  # the worker process dies, as when its node is lost

    backend = RayBackend()
    with pytest.raises(TrainingError, match=r"^timesteps: expected a positive integer, got 0$"):
        list(backend.run(refuse, [()]))
    with pytest.raises(BackendError, match=r"^the Ray cluster failed: \w+Error"):
        list(backend.run(crash, [()]))
    assert list(backend.run(lambda x: 2 * x, [(3,)])) == [(0, 6)]  # the cluster still serves the next study
