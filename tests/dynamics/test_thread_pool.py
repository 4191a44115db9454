"""The threads of the compiled batches: set_num_threads and get_num_threads resize the pool between
calls, the numbers are the same bits on any thread count, STEWART_ENV_THREADS is read once and a
value that is no count is refused with a warning naming it, and a process whose operating system
refuses threads (a capped address space) goes on with the threads it got."""

import os
import re
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

import stewart_env as se
from stewart_env.dynamics import threads

from physics_reference import random_state

pytestmark = pytest.mark.physics

LINUX = sys.platform.startswith("linux")


@pytest.fixture
def restore_threads():
    """Put the thread count back as it was after the test."""
    before = se.get_num_threads()
    yield
    se.set_num_threads(before)


def helper_threads(expected: int) -> int:
    """The pool's helper threads running in this process (Linux: by their name), waited for up to
    5 s to become ``expected`` (a helper told to stop takes a moment to leave the process)."""
    deadline = time.monotonic() + 5.0
    while True:
        names = []
        for task in Path("/proc/self/task").iterdir():
            try:
                names.append((task / "comm").read_text().strip())
            except OSError:  # the thread ended while listed
                pass
        count = names.count("stewart-helper")
        if count == expected or time.monotonic() > deadline:
            return count
        time.sleep(0.01)


def batch_of(params, n, seed=0):
    rng = np.random.default_rng(seed)
    t, R, v, w = (np.stack(x) for x in zip(*(random_state(params, rng, speed=0.5) for _ in range(n))))
    return t, R, v, w, 180 + 60 * rng.normal(size=(n, 6))


def test_a_batch_gives_the_same_bits_on_1_2_and_3_threads(dasgupta, restore_threads):
    model = se.make_dynamics("improved", dasgupta)
    t, R, v, w, F = batch_of(dasgupta, 1024)
    ws = model.workspace(1024)
    results = []
    for n in (1, 2, 3):
        assert se.set_num_threads(n) == n and se.get_num_threads() == n
        forward = np.hstack(model.forward(t, R, v, w, F))
        inverse = model.inverse(t, R, v, w, forward[:, :3], forward[:, 3:])
        ws.set_state(t, R, v, w)
        ws.leg_forces[:] = F
        ws.step(1e-3, steps=5)
        results.append((forward, inverse, ws.position.copy(), ws.rotation.copy(), ws.velocity.copy()))
    for other in results[1:]:
        for got, want in zip(other, results[0]):
            assert np.array_equal(got, want)


@pytest.mark.skipif(not LINUX, reason="counts the process's threads in /proc")
def test_set_num_threads_starts_and_stops_helper_threads(restore_threads):
    for n in (1, 4, 2, 3, 1):
        assert se.set_num_threads(n) == n and helper_threads(n - 1) == n - 1


@pytest.mark.parametrize("n", [0, -1, threads.MAX_THREADS + 1, 2.0, True, "2", None])
def test_set_num_threads_refuses_what_is_not_a_thread_count(n, restore_threads):
    before = se.get_num_threads()
    with pytest.raises(ValueError, match=rf"^n: expected an integer in \[1, {threads.MAX_THREADS}\], got"):
        se.set_num_threads(n)
    assert se.get_num_threads() == before


@pytest.mark.parametrize(
    "value, count, warning",
    [
        (None, None, None),
        ("", None, None),
        ("  ", None, None),
        ("1", 1, None),
        (" 12 ", 12, None),
        ("256", 256, None),
        ("257", 256, r"^STEWART_ENV_THREADS: 257 threads is above the most, 256; using 256$"),
        (
            "0",
            None,
            r"^STEWART_ENV_THREADS: expected a whole number of threads from 1 to 256, got '0'; using the default",
        ),
        ("-2", None, r"got '-2'; using the default"),
        ("1.5", None, r"got '1.5'; using the default"),
        ("four", None, r"got 'four'; using the default"),
        ("1_0", None, r"got '1_0'; using the default"),
    ],
)
def test_the_environment_variable_is_a_count_or_warned_about(value, count, warning):
    got, message = threads.threads_from_environment(value)
    assert got == count
    assert (message is None) if warning is None else re.search(warning, message)


def run_python(code: str, environment: dict, timeout: float = 60) -> subprocess.CompletedProcess:
    """Run ``code`` in a new interpreter with ``environment`` added to this one's; one line of
    numpy's own threads, so they take no part in what is measured."""
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", **environment}
    return subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)], env=env, capture_output=True, text=True, timeout=timeout
    )


def test_the_environment_variable_sets_the_threads_and_a_bad_one_is_named():
    code = "import stewart_env as se; print(se.get_num_threads())"
    assert run_python(code, {"STEWART_ENV_THREADS": "3"}).stdout.split() == ["3"]
    bad = run_python(code, {"STEWART_ENV_THREADS": "four"})
    default = run_python(code, {"STEWART_ENV_THREADS": ""})
    assert bad.returncode == 0 and bad.stdout == default.stdout
    assert (
        "RuntimeWarning: STEWART_ENV_THREADS: expected a whole number of threads from 1 to 256, got 'four'"
        in bad.stderr
    )
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    assert int(default.stdout) == min(cores, threads.MAX_THREADS)


@pytest.mark.skipif(not LINUX, reason="caps the address space with setrlimit and reads /proc")
def test_a_capped_address_space_gives_the_threads_the_system_allows_and_the_same_numbers(
    dasgupta, tmp_path, restore_threads
):
    """256 threads asked for in a process whose address space leaves room for a few thread stacks
    (8 MB each by default): the threads the system refuses are done without, the batch finishes
    (before, the process hung) and gives the numbers of one thread."""
    t, R, v, w, F = batch_of(dasgupta, 1024, seed=1)
    np.savez(tmp_path / "batch.npz", t=t, R=R, v=v, w=w, F=F)
    model = se.make_dynamics("improved", dasgupta)
    se.set_num_threads(1)
    want = np.hstack(model.forward(t, R, v, w, F))
    code = f"""
        import resource
        import numpy as np
        import stewart_env as se

        batch = np.load({str(tmp_path / "batch.npz")!r})
        model = se.make_dynamics("improved", se.load_platform("dasgupta1998"))
        with open("/proc/self/status") as status:
            size = next(int(line.split()[1]) * 1024 for line in status if line.startswith("VmSize:"))
        # the cap is set here, on the interpreter's own size once loaded, which varies by machine
        soft, hard = resource.getrlimit(resource.RLIMIT_AS)
        resource.setrlimit(resource.RLIMIT_AS, (size + (64 << 20), hard))
        out = [np.hstack(model.forward(batch["t"], batch["R"], batch["v"], batch["w"], batch["F"])) for _ in range(3)]
        started = se.get_num_threads()
        resource.setrlimit(resource.RLIMIT_AS, (soft, hard))
        np.save({str(tmp_path / "out.npy")!r}, np.stack(out))
        print(started)
    """
    try:
        done = run_python(code, {"STEWART_ENV_THREADS": "256"})
    except subprocess.TimeoutExpired:
        pytest.fail("a batch under a capped address space did not finish in 60 s")
    assert done.returncode == 0, done.stderr[-2000:]
    started = int(done.stdout)
    assert 1 <= started < 256  # the cap refused some threads: the case under test happened
    for got in np.load(tmp_path / "out.npy"):
        assert np.array_equal(got, want)
