"""Usage errors carry their argument as data; the command line names its flag; no code reads an
error's text to learn what went wrong."""

from __future__ import annotations

import ast
import math
from pathlib import Path

import pytest

from stewart_env.errors import UsageError

ROOT = Path(__file__).resolve().parents[1]

# -- the error class -----------------------------------------------------------------------------


def test_a_usage_error_carries_its_argument_and_problem():
    err = UsageError.about("control_dt", "expected a finite number in [1e-06, 10], got 0")
    assert (err.argument, err.problem) == ("control_dt", "expected a finite number in [1e-06, 10], got 0")
    assert str(err) == "control_dt: expected a finite number in [1e-06, 10], got 0" and isinstance(err, ValueError)
    assert UsageError("a file is busy").argument is None and UsageError("a file is busy").problem == "a file is busy"
    import pickle

    copy = pickle.loads(pickle.dumps(err))  # errors cross process boundaries (the mismatch study's workers)
    assert (copy.argument, copy.problem, str(copy)) == (err.argument, err.problem, str(err))


def test_the_subclasses_keep_their_fields():
    from stewart_env.params import ConfigError
    from stewart_env.validation import ArgumentError

    err = ConfigError("platform.mass", "expected a positive number", "a.yaml")
    assert (err.key, err.problem, err.source, err.argument) == (
        "platform.mass",
        "expected a positive number",
        "a.yaml",
        "platform.mass",
    )
    assert ConfigError("", "not a mapping").argument is None
    assert str(err) == "a.yaml: platform.mass: expected a positive number"
    bad = ArgumentError.about("seed", "expected an integer")
    assert isinstance(bad, TypeError) and isinstance(bad, UsageError) and bad.argument == "seed"


# -- the environment's keywords ------------------------------------------------------------------

#: A value of each environment keyword the environment refuses (the wrong kind, or out of range).
BAD_VALUES = {
    "model": "newton",
    "plant": "bullet",
    "platform": 3,
    "control_dt": 0.0,
    "physics_dt": -1.0,
    "randomization": {"platform.mass": (2.0, 1.0)},
    "task": "juggle",
    "task_options": [1],
    "version": 99,
    "max_force": -1.0,
    "action_filter": 2.0,
    "observation_noise": "loud",
    "observation_delay": 2.5,
    "render_mode": "paper",
    "width": 0,
    "height": 10**6,
}


def _env_keywords():
    from stewart_env.envs.keywords import DEFAULTS

    return list(DEFAULTS)


@pytest.mark.parametrize("name", _env_keywords())
def test_every_refused_environment_keyword_is_named_as_data(name):
    from stewart_env.envs import StewartPlatformEnv

    value = BAD_VALUES.get(name, object())
    with pytest.raises(ValueError) as info:
        StewartPlatformEnv(**{name: value})
    err = info.value
    if name == "randomization":  # a domain randomisation spec is a config: the error names its key
        from stewart_env.params import ConfigError

        assert isinstance(err, ConfigError) and err.key, err
        return
    assert isinstance(err, UsageError), repr(err)
    assert err.argument == name, f"{name}: {err!r} names {err.argument!r}"
    assert str(err).startswith(f"{name}") and err.problem in str(err)


def test_an_unknown_keyword_is_named_as_data():
    from stewart_env.envs import StewartPlatformEnv
    from stewart_env.envs.config import EnvConfig

    for make in (StewartPlatformEnv, EnvConfig.of):
        with pytest.raises(TypeError) as info:
            make(frameskip=4)
        assert isinstance(info.value, UsageError) and info.value.argument == "frameskip"
        assert "got an unexpected keyword argument 'frameskip'" in str(info.value)


def test_reset_options_are_named_as_data():
    from stewart_env.envs import StewartPlatformEnv

    env = StewartPlatformEnv()
    with pytest.raises(ValueError) as info:
        env.reset(options={"speed": 1})
    assert info.value.argument == "options" and str(info.value).startswith("reset: options: unknown option(s) 'speed'")
    env.close()


# -- the constraints, one set for keywords and flags ---------------------------------------------


def test_one_constraint_checks_a_keyword_and_reads_a_flag():
    import numbers

    from stewart_env.cli.arguments import real
    from stewart_env.validation import Interval, StrOptions

    dt = Interval(numbers.Real, 0, 10, low_open=True)
    assert dt.check("control_dt", 3) == 3.0 and dt.parse("0.5") == 0.5
    with pytest.raises(UsageError) as info:
        dt.check("control_dt", 0.0)
    assert (info.value.argument, info.value.problem) == ("control_dt", "expected a finite number in (0, 10], got 0.0")
    with pytest.raises(UsageError) as info:
        dt.parse("nan", "control_dt")
    assert (info.value.argument, info.value.problem) == ("control_dt", "expected a finite number in (0, 10], got 'nan'")
    import argparse

    with pytest.raises(argparse.ArgumentTypeError, match=r"^expected a finite number in \(0, 10\], got '0'$"):
        real(0, 10, low_open=True)("0")
    with pytest.raises(TypeError):  # a wrong kind is the caller's error, not the user's
        dt.check("control_dt", "0.5")
    steps = Interval(numbers.Integral, 1, 5)
    assert steps.parse("5") == 5 and steps.check("n", 2) == 2
    for text in ("6", "1.5", "x", "True"):
        with pytest.raises(UsageError, match=r"expected an integer in \[1, 5\]"):
            steps.parse(text)
    with pytest.raises(TypeError):
        steps.check("n", True)
    plants = StrOptions(("closed_form", "mujoco"))
    with pytest.raises(UsageError, match=r"^plant: expected one of 'closed_form', 'mujoco', got 'x'$"):
        plants.check("plant", "x")
    assert math.isinf(Interval(numbers.Real, 0, math.inf).high)


# -- the command line ----------------------------------------------------------------------------


def test_the_command_line_names_the_flag_of_an_argument(capsys):
    from stewart_env.cli.common import FLAGS, error, usage_message

    assert error("identify", UsageError.about("model", "unknown model 'x'")) == 2
    assert capsys.readouterr().err == "stewart-env identify: error: argument --model: unknown model 'x'\n"
    assert usage_message(UsageError.about("max_iterations", "too many")) == "argument --iterations: too many"
    # an argument no flag sets keeps the message that names it
    assert usage_message(UsageError.about("control_dt", "bad")) == "control_dt: bad"
    assert usage_message("plain text") == "plain text"
    assert all(flag.startswith("--") for flag in FLAGS.values())


def test_every_identification_setting_refused_names_its_flag():
    """Each setting's error carries the setting, and the command line has its flag."""
    from stewart_env.cli import build_parser
    from stewart_env.cli.common import FLAGS
    from stewart_env.identification.experiment import Settings

    flags = {
        o
        for action in build_parser()._subparsers._group_actions[0].choices["identify"]._actions
        for o in action.option_strings
    }
    bad = {
        "plant": "newton",
        "model": "improved+c9",
        "excitation": "sine",
        "derivatives": "guess",
        "duration": -1.0,
        "period": math.nan,
        "noise_position": -1.0,
        "noise_angle": math.inf,
        "noise_force": -2.0,
        "delay": 0.0021,
        "perturb": 1.5,
    }
    for name, value in bad.items():
        with pytest.raises(UsageError) as info:
            Settings(**{name: value}).check()
        assert info.value.argument == name, (name, info.value)
        assert FLAGS[name] in flags and str(info.value) == f"{FLAGS[name]}: {info.value.problem}"


@pytest.mark.parametrize(
    "argv, flag, problem",
    [
        (["evaluate", "--model", "newton"], "--model", "unknown model 'newton'; choose one of"),
        (["evaluate", "--internal-model", "mujoco"], "--internal-model", "unknown model 'mujoco'"),
        (["identify", "--plant", "improved+c5", "--out", "x"], "--plant", "unknown switch 'c5'"),
        (
            ["train", "--algo", "ppo", "--env-kwargs", "noequals", "--out", "x"],
            "--env-kwargs",
            "expected key=value or a JSON object",
        ),
        (["mismatch", "--cost-plant", "classical+c9", "--out", "x"], "--cost-plant", "unknown switch 'c9'"),
    ],
)
def test_a_bad_model_or_keyword_flag_is_argparse_error_naming_it(argv, flag, problem, capsys):
    from stewart_env.cli import main

    with pytest.raises(SystemExit) as info:
        main(argv)
    assert info.value.code == 2
    err = capsys.readouterr().err.splitlines()[-1]
    assert err.startswith(f"stewart-env {argv[0]}: error: argument {flag}: {problem}"), err


# -- no code reads an error's text ---------------------------------------------------------------

#: str methods that read a message's words.
TEXT_READERS = {
    "startswith",
    "endswith",
    "removeprefix",
    "removesuffix",
    "partition",
    "rpartition",
    "split",
    "rsplit",
    "find",
    "rfind",
    "index",
    "count",
    "replace",
}
#: Places that still read an error's text, each with the reason it cannot stop here.
KNOWN: set[tuple[str, str]] = set()


def _reads_error_text(handler: ast.ExceptHandler) -> bool:
    """Whether an ``except ... as e`` body looks into e's text: str(e) (or a name holding it, or
    e.args, or e.problem of a library error) read with a str method, ``in``, or a regex."""
    if handler.name is None:
        return False
    names = {handler.name}
    texts: set[str] = set()

    def is_text(node: ast.AST) -> bool:
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "str" and node.args:
            inner = node.args[0]
            return (isinstance(inner, ast.Name) and inner.id in names) or (
                isinstance(inner, ast.Attribute) and isinstance(inner.value, ast.Name) and inner.value.id in names
            )
        if isinstance(node, ast.Subscript) and isinstance(node.value, ast.Attribute) and node.value.attr == "args":
            return isinstance(node.value.value, ast.Name) and node.value.value.id in names
        return isinstance(node, ast.Name) and node.id in texts

    for node in ast.walk(ast.Module(body=handler.body, type_ignores=[])):
        if isinstance(node, ast.Assign) and is_text(node.value):
            texts.update(t.id for t in node.targets if isinstance(t, ast.Name))
    for node in ast.walk(ast.Module(body=handler.body, type_ignores=[])):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute):
            if node.func.attr in TEXT_READERS and is_text(node.func.value):
                return True
            if node.func.attr in ("match", "search", "fullmatch", "findall") and any(is_text(a) for a in node.args):
                return True
        if isinstance(node, ast.Compare) and any(isinstance(op, (ast.In, ast.NotIn)) for op in node.ops):
            if any(is_text(c) for c in node.comparators):
                return True
    return False


def _functions(tree: ast.AST):
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            yield node


def test_the_text_reader_finds_what_it_looks_for():
    code = """
def f():
    try:
        pass
    except ValueError as err:
        if not str(err).startswith("model: unknown"):
            raise
def g():
    try:
        pass
    except ValueError as err:
        message = str(err)
        return "pip install" in message
def h():
    try:
        pass
    except ValueError as err:
        raise KeyError(err.problem) from None
"""
    found = [
        fn.name
        for fn in _functions(ast.parse(code))
        for h in ast.walk(fn)
        if isinstance(h, ast.ExceptHandler) and _reads_error_text(h)
    ]
    assert found == ["f", "g"]


def test_no_module_reads_an_error_text():
    found = set()
    for top in ("stewart_env", "agents"):
        for path in sorted((ROOT / top).rglob("*.py")):
            tree = ast.parse(path.read_text(), str(path))
            for fn in _functions(tree):
                for handler in (n for n in ast.walk(fn) if isinstance(n, ast.ExceptHandler)):
                    if _reads_error_text(handler):
                        found.add((path.relative_to(ROOT).as_posix(), fn.name))
    assert found - KNOWN == set(), "code that reads an error's text (raise errors that carry data instead)"
    assert KNOWN - found == set(), "a known place no longer reads error text: remove it from KNOWN"


def test_the_study_checks_its_counts_with_the_command_lines_constraints():
    """MismatchSettings' counts and tolerances are the constraints' checks: the error names the
    setting as data, and a numpy integer is a count."""
    import numpy as np

    from stewart_env.agents.studies.mismatch.settings import COUNT, TOLERANCE, _checked

    assert _checked(COUNT, "episodes", np.int64(3)) == 3 and _checked(TOLERANCE, "position_tolerance", 1) == 1.0
    cases = (
        ("episodes", COUNT, 0),
        ("n_envs", COUNT, True),
        ("position_tolerance", TOLERANCE, 0.0),
        ("orientation_tolerance", TOLERANCE, math.nan),
    )
    for name, constraint, value in cases:
        with pytest.raises(UsageError) as info:
            _checked(constraint, name, value)
        assert info.value.argument == name and str(info.value).startswith(f"{name}: expected {constraint.expected}")
