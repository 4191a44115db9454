"""The mismatch study on a Ray cluster of several nodes, joined by its address as the cluster
commands of docs/guides/mismatch.md do: every job runs on a node other than the driver's, and the
matrix is the local backend's."""

from __future__ import annotations

import pytest

ray = pytest.importorskip("ray")
cluster_utils = pytest.importorskip("ray.cluster_utils")

# PPO runs here are a rollout of 2 platforms, smaller than the config's minibatch on purpose.
pytestmark = [
    pytest.mark.filterwarnings("ignore:You have specified a mini-batch size:UserWarning"),
    pytest.mark.slow,
]  # three Ray nodes start in about 10-20 s

from stewart_env.agents.studies.mismatch import run_mismatch  # noqa: E402

from test_ray import STUDY, _numbers  # noqa: E402  the tiny study of the single-node tests


@pytest.fixture
def cluster():
    # a head node with no CPUs (it schedules, it runs no job) and two worker nodes of one CPU each
    nodes = cluster_utils.Cluster(initialize_head=True, head_node_args={"num_cpus": 0})
    for _ in range(2):
        nodes.add_node(num_cpus=1)
    nodes.wait_for_nodes()
    yield nodes
    ray.shutdown()
    nodes.shutdown()


def test_a_study_on_a_cluster_of_three_nodes_runs_its_jobs_on_the_workers_and_matches_local(cluster, tmp_path):
    from ray.util.state import list_tasks

    on_cluster = run_mismatch(tmp_path / "cluster", backend="ray", ray_address=cluster.address, **STUDY)
    ray.init(address=cluster.address, logging_level="ERROR", log_to_driver=False)
    jobs = [t for t in list_tasks(limit=1000) if t.name in ("train_job", "evaluate_job")]
    # one job per agent (two rows, two seeds) and one per stored cell
    cells = list((tmp_path / "cluster" / "cells").rglob("*.json"))
    assert [t.name for t in jobs].count("train_job") == 4 and len(jobs) == 4 + len(cells) > 4
    assert all(t.state == "FINISHED" for t in jobs)
    # on the worker nodes, never the head (it has no CPU): what the jobs need travelled to them
    workers = {n["NodeID"] for n in ray.nodes() if n["Resources"].get("CPU")}
    assert len(workers) == 2 and {t.node_id for t in jobs} <= workers
    ray.shutdown()
    local = run_mismatch(tmp_path / "local", backend="local", **STUDY)
    assert [r.label for r in on_cluster.rows] == [r.label for r in local.rows]
    assert _numbers(tmp_path / "cluster") == _numbers(tmp_path / "local")
