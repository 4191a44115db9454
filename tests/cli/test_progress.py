"""Progress bars on terminals only; in logs at most one line per minute."""

import io

import pytest
from tqdm.auto import tqdm

from stewart_env import progress as progress_module
from stewart_env.progress import QuietProgress, on_terminal, progress


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


class Clock:
    """A stand-in for time.monotonic that the test moves by hand."""

    def __init__(self):
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


def test_a_terminal_gets_a_tqdm_bar(monkeypatch):
    monkeypatch.setattr("sys.stderr", Terminal())
    assert on_terminal()
    bar = progress(range(3), desc="run")
    assert isinstance(bar, tqdm)
    assert list(bar) == [0, 1, 2]


def test_a_log_gets_at_most_one_line_per_minute(monkeypatch):
    log = io.StringIO()
    clock = Clock()
    monkeypatch.setattr("sys.stderr", log)
    monkeypatch.setattr(progress_module.time, "monotonic", clock)
    assert not on_terminal()
    with progress(total=1000, desc="case study", unit="step") as bar:
        assert isinstance(bar, QuietProgress)
        bar.set_postfix_str("improved")
        for _ in range(1000):  # 1000 steps over 125 s (0.125 s is exact in binary): lines at 60 s and 120 s
            clock.now += 0.125
            bar.update()
    lines = log.getvalue().splitlines()
    assert len(lines) == 2
    assert lines[0].startswith("case study: 480/1000 step (improved), 60 s")


def test_a_short_run_in_a_log_writes_nothing(monkeypatch):
    log = io.StringIO()
    monkeypatch.setattr("sys.stderr", log)
    assert list(progress(["a", "b"], desc="cells")) == ["a", "b"]
    assert log.getvalue() == ""


@pytest.mark.parametrize("stream", [Terminal(), io.StringIO()])
def test_disable_silences_both(monkeypatch, stream):
    clock = Clock()
    monkeypatch.setattr("sys.stderr", stream)
    monkeypatch.setattr(progress_module.time, "monotonic", clock)
    bar = progress(total=10, disable=True)
    for _ in range(10):
        clock.now += 100.0
        bar.update()
    bar.close()
    assert stream.getvalue() == ""
