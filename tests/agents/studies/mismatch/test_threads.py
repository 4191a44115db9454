"""The study's workers size the physics threads to the CPUs they were given: jobs side by side on
one machine share its cores instead of each taking all of them; --physics-threads N sets another
count for every job."""

from __future__ import annotations

import pytest

import stewart_env as se
from stewart_env.agents.studies.mismatch import LocalBackend, MismatchError, MismatchSettings, make_backend
from stewart_env.agents.studies.mismatch.constants import CPUS_PER_JOB
from stewart_env.agents.studies.mismatch.jobs import on_threads
from stewart_env.cli import main


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
        sized = [count for _, count in RayBackend(threads=2).run(se.get_num_threads, [(), ()])]
    finally:
        ray.shutdown()
    assert counts == [CPUS_PER_JOB] * 3
    assert sized == [2, 2]  # --physics-threads 2: every job on two threads, whatever its CPUs


def test_physics_threads_are_auto_or_a_count_and_not_recorded():
    assert MismatchSettings(algo=None).physics_threads == "auto"
    settings = MismatchSettings(algo=None, physics_threads=3)
    assert settings.physics_threads == 3 and "physics_threads" not in settings.recorded()  # same numbers on any count
    for bad in (0, 257, "four", True, 1.5):
        with pytest.raises(MismatchError, match="physics_threads") as caught:
            MismatchSettings(algo=None, physics_threads=bad)
        assert caught.value.argument == "physics_threads"


def test_the_local_backend_runs_on_the_threads_asked_and_gives_them_back(restore_threads):
    se.set_num_threads(3)
    backend = make_backend("local", None, 1)
    assert [count for _, count in backend.run(se.get_num_threads, [(), ()])] == [1, 1]
    backend.close()
    assert se.get_num_threads() == 3
    backend = make_backend("local", None, "auto")  # this process's own count
    assert isinstance(backend, LocalBackend) and [n for _, n in backend.run(se.get_num_threads, [()])] == [3]
    backend.close()
    assert se.get_num_threads() == 3


@pytest.mark.parametrize(
    "value, message",
    [
        ("0", "argument --physics-threads: expected 'auto' or an integer from 1 to 256, got '0'"),
        ("many", "argument --physics-threads: expected 'auto' or an integer from 1 to 256, got 'many'"),
    ],
)
def test_the_command_line_refuses_a_bad_thread_count(value, message, tmp_path, capsys):
    with pytest.raises(SystemExit) as stop:
        main(["mismatch", "--algo", "none", "--physics-threads", value, "--out", str(tmp_path / "s")])
    assert stop.value.code == 2
    assert message in capsys.readouterr().err


def test_the_command_line_passes_the_thread_count_to_the_study(monkeypatch, tmp_path):
    from stewart_env.cli import mismatch as command

    seen = []

    def run_mismatch(out, *args, **kwargs):
        seen.append(kwargs["physics_threads"])
        raise MismatchError("stopped after the settings")

    monkeypatch.setattr(command, "run_mismatch", run_mismatch)
    for value in ("AUTO", "2"):
        main(["mismatch", "--algo", "none", "--physics-threads", value, "--out", str(tmp_path / "s")])
    assert seen == ["auto", 2]
