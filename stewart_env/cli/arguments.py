"""argparse types shared by the command-line verbs: each turns a bad value into argparse's error
naming the argument (``stewart-env <verb>: error: argument --x: ...``, exit status 2).

The ranges are the package's declarative constraints (:class:`stewart_env.validation.Interval`,
:class:`~stewart_env.validation.StrOptions`), the same objects that check the environment's
keywords; a library check refused here is read from the error's data
(:attr:`stewart_env.errors.UsageError.problem`), never from its text."""

from __future__ import annotations

import argparse
import math
import numbers
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from stewart_env.agents.studies.mismatch.constants import MAX_STEPS as MAX_EPISODE_STEPS
from stewart_env.errors import UsageError
from stewart_env.tasks import TASKS as _TASK_CLASSES
from stewart_env.validation import MAX_SEED, Constraint, Interval, StrOptions, quoted

if TYPE_CHECKING:
    from stewart_env.dynamics import ModelSpec

#: The task names the command line offers: those of the task registry.
TASKS = tuple(_TASK_CLASSES)


#: Largest count a command takes (steps, iterations, checkpoints): numpy's int64, where counts end up.
MAX_COUNT = 2**63 - 1


def checked(cast: Callable[[str], float], ok: Callable[[float], bool], expected: str, doc: str):
    """An argparse type: ``cast(text)`` if it converts and passes ``ok``, else an error saying
    what was expected.

    Args:
        cast: converts the text to a value (raising ValueError or OverflowError if it cannot).
        ok: whether a converted value is accepted.
        expected: what the error says was expected, e.g. ``"a positive integer"``.
        doc: the docstring of the type (argparse's help shows nothing of it; the API pages do).
    """

    def parse(text: str):
        try:
            value = cast(text)
        except (ValueError, OverflowError):
            value = None
        if value is None or not ok(value):
            raise argparse.ArgumentTypeError(f"expected {expected}, got {quoted(text)}")
        return value

    parse.__doc__ = doc
    return parse


def constrained(constraint: Constraint, doc: str | None = None):
    """The argparse type of a declarative constraint: its value, or argparse's error in the
    constraint's words.

    Args:
        constraint: the declarative constraint (:mod:`stewart_env.validation`).
        doc: the type's docstring (default one saying what the constraint accepts).
    """

    def parse(text: str):
        try:
            return constraint.parse(text)
        except UsageError as err:
            raise argparse.ArgumentTypeError(err.problem) from None

    parse.__doc__ = doc or f"argparse type: {constraint.expected}."
    return parse


def integer(low: int, high: int, expected: str | None = None, doc: str | None = None):
    """An argparse type: an integer in [low, high] (``expected``: how the error says it).

    Args:
        low: the smallest integer accepted.
        high: the largest integer accepted.
        expected: how the error says what is accepted (default in the bounds' own words).
        doc: the type's docstring.
    """
    return constrained(Interval(numbers.Integral, low, high, expected=expected), doc)


def real(
    low: float, high: float = math.inf, *, low_open: bool = False, expected: str | None = None, doc: str | None = None
):
    """An argparse type: a finite number in [low, high] ((low, high] with ``low_open``).

    Args:
        low: the lower bound.
        high: the upper bound (default none).
        low_open: exclude ``low``.
        expected: how the error says what is accepted (default in the bounds' own words).
        doc: the type's docstring.
    """
    return constrained(Interval(numbers.Real, low, high, low_open=low_open, expected=expected), doc)


positive_int = integer(1, MAX_COUNT, f"a positive integer up to {MAX_COUNT}", "argparse type: an integer >= 1.")
nonnegative_int = integer(
    0, MAX_COUNT, f"an integer >= 0, up to {MAX_COUNT}", "argparse type: an integer >= 0 (step counts that may be 0)."
)
positive_float = real(0, low_open=True, expected="a finite positive number", doc="argparse type: a finite number > 0.")
nonnegative_float = real(
    0, expected="a finite number >= 0", doc="argparse type: a finite number >= 0 (noise levels, targets that may be 0)."
)
finite_float = real(-math.inf, expected="a finite number", doc="argparse type: a finite number.")
fraction = real(0, 1, expected="a number in [0, 1]", doc="argparse type: a fraction in [0, 1].")
#: A seed: numpy takes any, but the seeds passed on to outside libraries must fit 32 bits.
seed = integer(0, MAX_SEED, doc="argparse type: a seed, an integer in [0, 2**32 - 1].")
#: An evaluation episode's length in control steps: a record of every step is kept.
episode_steps = integer(1, MAX_EPISODE_STEPS, doc="argparse type of --max-steps: an integer in [1, MAX_STEPS].")


def platform_count(text: str) -> int:
    """Argparse type: a number of platforms simulated in one batch (--n-envs, --episodes): an
    integer in [1, 2**31 - 1] whose batch fits in the memory this machine has available
    (:func:`stewart_env.envs.vector.check_batch_memory`).

    Args:
        text: the command-line text.
    """
    from stewart_env.envs.vector import MAX_NUM_ENVS, check_batch_memory

    count = integer(1, MAX_NUM_ENVS, f"a positive integer up to {MAX_NUM_ENVS}")(text)
    try:
        check_batch_memory("", count)
    except UsageError as err:
        raise argparse.ArgumentTypeError(err.problem) from None
    return count


def distinct_list(item: Callable[[str], Any], example: str, expected: str | None = None):
    """An argparse type: comma-separated values, each checked by the argparse type ``item``, at
    least one, none twice (``example``: a valid value the error shows; ``expected``: if given,
    the one thing every error says was expected, instead of what is wrong with the list).

    Args:
        item: the argparse type of one value.
        example: a valid value the error shows.
        expected: if given, the one thing every error says was expected.
    """

    def parse(text: str) -> list:
        def refuse(problem: str) -> argparse.ArgumentTypeError:
            return argparse.ArgumentTypeError(
                problem if expected is None else f"expected {expected}, got {quoted(text)}"
            )

        names = [t.strip() for t in text.split(",") if t.strip()]  # blanks dropped: "a,b," is a,b
        if not names:
            raise refuse(f"expected a comma-separated list such as {example}, got {quoted(text)}")
        try:
            values = [item(n) for n in names]
        except argparse.ArgumentTypeError as err:
            raise refuse(str(err)) from None
        twice = sorted({str(v) for v in values if values.count(v) > 1})
        if twice:
            raise refuse(f"{', '.join(twice)} given twice in {quoted(text)}")
        return values

    parse.__doc__ = f"argparse type: comma-separated values, e.g. {example}, each once."
    return parse


seed_list = distinct_list(seed, "0,1,2", f"comma-separated distinct integers in [0, {MAX_SEED}], e.g. 0,1,2")


def choice(names: Sequence[str]):
    """An argparse type: one of ``names`` (for a value inside a list; a flag of its own uses
    argparse's ``choices``).

    Args:
        names: the accepted names, in the order the error lists them.
    """
    return constrained(StrOptions(names), doc=f"argparse type: one of {', '.join(names)}.")


def writable_file(text: str) -> str:
    """Argparse type: the path of a file to write: not a directory, in a folder that exists.

    Args:
        text: the command-line text.
    """
    path = Path(text)
    if not text.strip():
        raise argparse.ArgumentTypeError("expected a file name, got ''")
    if path.is_dir():
        raise argparse.ArgumentTypeError(f"{quoted(text)} is a directory; give the file's name")
    if not path.parent.is_dir():
        raise argparse.ArgumentTypeError(f"no such folder: {quoted(str(path.parent))}")
    return text


def directory_name(text: str) -> str:
    """Argparse type of --out: a non-blank path (whether it can be written is checked before any
    work, :func:`stewart_env.cli.common.check_out`).

    Args:
        text: the command-line text.
    """
    if not text.strip():
        raise argparse.ArgumentTypeError("expected a directory, got ''")
    return text


def existing_file(text: str) -> str:
    """Argparse type: the path of an existing file.

    Args:
        text: the command-line text.
    """
    if not Path(text).is_file():
        raise argparse.ArgumentTypeError(f"no such file: {text!r}")
    return text


#: How --platform tells a shipped platform's name from a config file's path (load_platform's rule).
PLATFORM_RULE = "a name has no / and no .yaml or .yml suffix, whatever the working directory holds"


def existing_directory(text: str) -> str:
    """Argparse type: the path of an existing directory.

    Args:
        text: the command-line text.
    """
    if not Path(text).is_dir():
        raise argparse.ArgumentTypeError(f"no such directory: {quoted(text)}")
    return text


def platform_name(text: str) -> str:
    """Argparse type: a shipped platform's name or a platform YAML file that loads.

    Args:
        text: the command-line text.
    """
    from stewart_env.params import load_platform

    try:
        load_platform(text)
    except (ValueError, OSError, KeyError, TypeError) as err:
        raise argparse.ArgumentTypeError(str(err)) from None
    return text


def model_name(text: str) -> ModelSpec:
    """Argparse type: a dynamics model's name (classical, improved, ... with +c1..+c4 switches)
    parsed once into its :class:`stewart_env.dynamics.ModelSpec`, which the command passes on.

    Args:
        text: the command-line text.

    Returns:
        The model's spec (``str(spec)`` is its canonical name).
    """
    from stewart_env.dynamics import ModelSpec

    try:
        return ModelSpec.parse(text)
    except UsageError as err:
        raise argparse.ArgumentTypeError(err.problem) from None


def plant_model_name(text: str) -> ModelSpec | str:
    """Argparse type: a value of the environment's ``model`` argument, parsed once: a dynamics
    model's :class:`~stewart_env.dynamics.ModelSpec` (see :func:`model_name`), or ``"mujoco"``,
    MuJoCo's simulation of the same mechanism (a plant only: it has no closed-form dynamics for a
    controller to use), as the environment's configuration reads it
    (:func:`stewart_env.envs.config.model_spec`).

    Args:
        text: the command-line text.

    Returns:
        The model's spec, or ``"mujoco"``.
    """
    from stewart_env.envs.config import MUJOCO, model_spec

    try:
        spec = model_spec(text)
    except UsageError as err:
        raise argparse.ArgumentTypeError(err.problem) from None
    return MUJOCO if spec is None else spec


#: A list of plants: dynamics model names (with +c1..+c4 switches) or mujoco.
plant_list = distinct_list(plant_model_name, "classical,improved")


def env_kwargs_token(text: str) -> str:
    """Argparse type of one --env-kwargs token: checked here, so that a bad one is an argparse error.

    Args:
        text: the command-line text.
    """
    from stewart_env.agents.training import TrainingError, parse_env_kwargs

    try:
        parse_env_kwargs([text])
    except TrainingError as exc:
        raise argparse.ArgumentTypeError(exc.problem) from None
    return text


def agent_config(text: str) -> str:
    """Argparse type of --config: a hyperparameter file's path, or a shipped config's name
    (``ppo_6m`` or ``ppo_6m.yml``), as the path of that file.

    Args:
        text: the command-line text.
    """
    from stewart_env.agents.training import TrainingError, config_path

    try:
        return str(config_path("", text))
    except TrainingError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
