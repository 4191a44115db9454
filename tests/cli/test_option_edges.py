"""Every option of every verb refuses a bad value at the edge: argparse's one line
``stewart-env <verb>: error: argument --flag: ...`` with exit status 2, before any work and
without a traceback."""

import subprocess
import sys

import pytest

from stewart_env.cli import main
from stewart_env.envs import vector

from conftest import exit_code

#: The estimator itself, before the fixture below stands in for it.
AVAILABLE_MEMORY = vector.available_memory

BIG = "1" + "0" * 30
#: The bad values of a number: not a number, not finite, zero, negative, beyond any range.
NUMBERS = ["nan", "inf", "-1", "0", "1e308", BIG, "abc", ""]
#: What each verb needs besides the option under test ({out}: a fresh folder).
REQUIRED = {
    "reproduce": ["--out", "{out}"],
    "train": ["--algo", "ppo", "--out", "{out}"],
    "time-to-agent": ["--algo", "ppo", "--out", "{out}"],
    "mismatch": ["--out", "{out}", "--algo", "none"],
    "identify": ["--out", "{out}"],
    "export-mjcf": ["--platform", "dasgupta1998", "--out", "{out}/m.xml"],
}


def cases():
    table = {
        ("demo", "--episodes"): NUMBERS,
        ("demo", "--seed"): [*NUMBERS[:3], BIG, str(2**32)],
        ("demo", "--platform"): ["nowhere", "", "é"],
        ("demo", "--out"): [""],
        ("evaluate", "--episodes"): NUMBERS,
        ("evaluate", "--seed"): [BIG, str(2**32)],
        ("evaluate", "--max-steps"): [*NUMBERS, str(10**8)],
        ("evaluate", "--internal-model"): ["nowhere", "", "é"],
        ("evaluate", "--model"): ["nowhere", "", "é"],
        ("evaluate", "--platform"): ["nowhere", ""],
        ("evaluate", "--out"): [""],
        ("reproduce", "--dt"): [*NUMBERS, "1e-300", "0.02"],
        ("reproduce", "--duration"): [*NUMBERS, "1e6"],
        ("reproduce", "--out"): [""],
        ("reproduce", "--platform"): ["nowhere"],
        ("train", "--timesteps"): NUMBERS,
        ("train", "--n-envs"): [*NUMBERS, "100000000"],
        ("train", "--seed"): [BIG, str(2**32)],
        ("train", "--checkpoint-freq"): ["nan", "-1", BIG, "abc"],
        ("train", "--keep-checkpoints"): ["0", BIG],
        ("train", "--model"): ["nowhere", "", "é"],
        ("train", "--config"): ["nowhere", ""],
        ("train", "--out"): [""],
        ("time-to-agent", "--seeds"): ["", ",", "0,0", "-1", "nan", BIG],
        ("time-to-agent", "--target-success"): [*NUMBERS[:3], "2"],
        ("time-to-agent", "--target-error-mm"): NUMBERS[:3],
        ("time-to-agent", "--budget"): NUMBERS,
        ("time-to-agent", "--interval"): NUMBERS,
        ("time-to-agent", "--episodes"): NUMBERS,
        ("time-to-agent", "--out"): [""],
        ("mismatch", "--train-models"): ["nowhere", "", ",", "é", "improved,improved"],
        ("mismatch", "--test-models"): ["nowhere", "", "improved,improved"],
        ("mismatch", "--agent-models"): ["nowhere", ","],
        ("mismatch", "--cost-plant"): ["nowhere", "", "classical+c9"],
        ("mismatch", "--simplifications"): ["c9", "", "c1,c1"],
        ("mismatch", "--timesteps"): NUMBERS,
        ("mismatch", "--n-envs"): [*NUMBERS, "100000000"],
        ("mismatch", "--episodes"): NUMBERS,
        ("mismatch", "--max-steps"): NUMBERS,
        ("mismatch", "--position-tolerance"): NUMBERS[:4],
        ("mismatch", "--orientation-tolerance"): NUMBERS[:4],
        ("mismatch", "--seeds"): ["", "0,0", str(2**32)],
        ("mismatch", "--controller-platform"): ["nowhere", "", "lab=nowhere"],
        ("mismatch", "--out"): [""],
        ("identify", "--duration"): [*NUMBERS, "1", "4000"],
        ("identify", "--period"): [*NUMBERS, "0.01"],
        ("identify", "--noise-position"): NUMBERS[:3] + ["1e308"],
        ("identify", "--noise-angle"): ["nan", "1e308"],
        ("identify", "--noise-force"): ["inf", "-1", "1e308"],
        ("identify", "--delay"): ["nan", "inf", "-1", "1e308", BIG, "abc", "", "0.003", "1"],
        ("identify", "--perturb"): ["nan", "-1", "1", "5"],
        ("identify", "--iterations"): ["0", BIG, "nan"],
        ("identify", "--seed"): ["-1", str(2**32)],
        ("identify", "--plant"): ["nowhere", "", "é"],
        ("identify", "--model"): ["nowhere", "", "mujoco"],
        ("identify", "--platform"): ["nowhere"],
        ("identify", "--out"): [""],
        ("bench", "--models"): ["nowhere", "", ",", "improved,improved", "é"],
        ("bench", "--platform"): ["nowhere", ""],
        ("bench", "--plot"): ["{out}/missing/plot.png", "{out}/..", ""],
        ("export-mjcf", "--timestep"): NUMBERS,
        ("export-mjcf", "--platform"): ["nowhere", ""],
    }
    for (verb, flag), values in table.items():
        # a time step argparse takes is checked after export-mjcf has named a missing mujoco extra
        marks = [pytest.mark.extra("mujoco")] if (verb, flag) == ("export-mjcf", "--timestep") else []
        for value in values:
            yield pytest.param(verb, flag, [value], id=f"{verb} {flag} {value[:12]!r}", marks=marks)
    for flag, values in (
        ("--solref", [["nan", "1"], ["1", "inf"], ["abc", "1"]]),
        ("--solimp", [["nan", "0.95", "0.001", "0.5", "2"], ["0.9", "0.95", "0.001", "0.5", "inf"]]),
    ):
        for value in values:
            yield pytest.param("export-mjcf", flag, value, id=f"export-mjcf {flag} {' '.join(value)}")


def argv_of(verb, flag, values, out):
    required = list(REQUIRED.get(verb, []))
    if flag in required:  # the option under test takes the required one's place
        i = required.index(flag)
        del required[i : i + 2]
    return [
        verb,
        *(a.replace("{out}", str(out)) for a in required),
        flag,
        *(v.replace("{out}", str(out)) for v in values),
    ]


@pytest.fixture(autouse=True)
def _memory(monkeypatch):
    """A machine with 16 GB available, whatever this one has: the memory refusals are the same on any."""
    monkeypatch.setattr(vector, "available_memory", lambda: 16 * 10**9)


@pytest.mark.parametrize("verb, flag, values", cases())
def test_a_bad_value_is_argparses_error_naming_the_flag(verb, flag, values, tmp_path, capsys):
    out = tmp_path / "out"
    argv = argv_of(verb, flag, values, out)
    code = exit_code(argv)  # argparse's own exit, or the same line from a check right after parsing
    err = capsys.readouterr().err
    assert code == 2, err
    last = err.strip().splitlines()[-1]
    assert last.startswith(f"stewart-env {verb}: error: argument {flag}: "), err
    assert "Traceback" not in err and len(last) < 400  # a huge value is quoted cut, not whole
    assert not out.exists()


@pytest.mark.parametrize(
    "argv, flag",
    [
        (["reproduce", "--out", "{out}", "--duration", "0.001", "--dt", "0.002"], "--dt"),  # longer than --duration
        (["reproduce", "--out", "{out}", "--duration", "50", "--dt", "1e-5"], "--dt"),  # 5e6 steps
        (["evaluate", "--model", "improved", "improved"], "--model"),
        (["mismatch", "--out", "{out}", "--algo", "none", "--env-kwargs", "contol_dt=0.02"], "--env-kwargs"),
        (["mismatch", "--out", "{out}", "--algo", "none", "--env-kwargs", "control_dt=-1"], "--env-kwargs"),
        (["mismatch", "--out", "{out}", "--algo", "none", "--ray-address", "auto"], "--ray-address"),
        pytest.param(
            ["mismatch", "--out", "{out}", "--algo", "none", "--backend", "ray", "--ray-address", ""],
            "--ray-address",
            marks=pytest.mark.extra("distributed"),
        ),  # without ray, the extra is named first
        (["time-to-agent", "--algo", "ppo", "--out", "{out}", "--config", "nowhere"], "--config"),
        (["evaluate", "--policy", "pd", "pd"], "--policy"),
        (["evaluate", "--episodes", "100000", "--max-steps", "1000000"], "--episodes"),  # the record of every step
    ],
)
def test_options_that_cannot_run_together_are_refused_naming_the_flag(argv, flag, tmp_path, capsys):
    out = tmp_path / "out"
    assert main([a.replace("{out}", str(out)) for a in argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"stewart-env {argv[0]}: error: argument {flag}: ") and len(err.splitlines()) == 1, err
    assert not out.exists()


def test_a_batch_larger_than_the_memory_says_the_estimate_and_what_is_available(capsys):
    with pytest.raises(SystemExit):
        main(["train", "--algo", "ppo", "--out", "unused", "--n-envs", "100000000"])
    last = capsys.readouterr().err.strip().splitlines()[-1]
    # 4096 bytes a platform (vector.BYTES_PER_PLATFORM) times 1e8, against the 16 GB of the fixture
    assert last.endswith(
        "argument --n-envs: 100000000 platforms do not fit in this machine's memory: they need "
        "about 410 GB, 16 GB is available"
    ), last


def test_the_vector_env_refuses_a_batch_larger_than_the_memory_before_allocating(monkeypatch):
    import gymnasium as gym

    import stewart_env  # noqa: F401  (registers the environment)

    monkeypatch.setattr(vector, "available_memory", lambda: 10**6)  # 1 MB: 245 platforms at most
    with pytest.raises(
        ValueError,
        match=r"^num_envs: 1000 platforms do not fit in this machine's memory: they "
        r"need about 4.1 MB, 1 MB is available$",
    ):
        gym.make_vec("StewartPlatform-v1", num_envs=1000, vectorization_mode="vector_entry_point")
    monkeypatch.setattr(vector, "available_memory", lambda: None)  # unknown: no check
    gym.make_vec("StewartPlatform-v1", num_envs=300, vectorization_mode="vector_entry_point").close()


def test_available_memory_falls_back_to_the_physical_memory_then_to_nothing(monkeypatch):
    import builtins

    real_open = builtins.open

    def no_meminfo(path, *args, **kwargs):
        if str(path) == "/proc/meminfo":
            raise FileNotFoundError(path)
        return real_open(path, *args, **kwargs)

    monkeypatch.setattr(builtins, "open", no_meminfo)
    monkeypatch.setattr(
        vector.os, "sysconf", lambda name: {"SC_PHYS_PAGES": 1000, "SC_PAGE_SIZE": 4096}[name], raising=False
    )
    assert AVAILABLE_MEMORY() == 4096000
    monkeypatch.delattr(vector.os, "sysconf")
    assert AVAILABLE_MEMORY() is None


@pytest.mark.parametrize(
    "argv, flag",
    [
        (["bench", "--models", "nowhere"], "--models"),
        (["identify", "--out", "{out}", "--period", "nan"], "--period"),
        (["demo", "--episodes", BIG], "--episodes"),
    ],
)
def test_the_installed_command_prints_one_line_without_a_traceback(argv, flag, tmp_path):
    argv = [a.replace("{out}", str(tmp_path / "out")) for a in argv]
    done = subprocess.run([sys.executable, "-m", "stewart_env.cli", *argv], capture_output=True, text=True, timeout=120)
    assert done.returncode == 2
    assert f"stewart-env {argv[0]}: error: argument {flag}: " in done.stderr and "Traceback" not in done.stderr


def test_no_arguments_prints_the_help_naming_the_environment_and_the_quick_start(capsys):
    assert main([]) == 0
    out = capsys.readouterr().out
    assert out.startswith("usage: stewart-env")
    assert "StewartPlatform-v1" in out and "stewart-env demo" in out and 'gym.make("StewartPlatform-v1")' in out
