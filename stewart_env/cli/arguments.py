"""argparse types shared by the command-line verbs: each turns a bad value into argparse's error
naming the argument (``stewart-env <verb>: error: argument --x: ...``, exit status 2)."""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from pathlib import Path

from stewart_env.tasks import TASKS as _TASK_CLASSES

#: The task names the command line offers: those of the task registry.
TASKS = tuple(_TASK_CLASSES)


def checked(cast: Callable[[str], float], ok: Callable[[float], bool], expected: str, doc: str):
    """An argparse type: ``cast(text)`` if it converts and passes ``ok``, else an error saying
    what was expected."""

    def parse(text: str):
        try:
            value = cast(text)
        except (ValueError, OverflowError):
            value = None
        if value is None or not ok(value):
            raise argparse.ArgumentTypeError(f"expected {expected}, got {text!r}")
        return value

    parse.__doc__ = doc
    return parse


positive_int = checked(int, lambda v: v >= 1, "a positive integer", "argparse type: an integer >= 1.")
nonnegative_int = checked(int, lambda v: v >= 0, "an integer >= 0",
                           "argparse type: an integer >= 0 (seeds, step counts that may be 0).")
positive_float = checked(float, lambda v: v > 0 and math.isfinite(v), "a finite positive number",
                          "argparse type: a finite number > 0.")
nonnegative_float = checked(float, lambda v: v >= 0 and math.isfinite(v), "a finite number >= 0",
                             "argparse type: a finite number >= 0 (noise levels, targets that may be 0).")


def existing_file(text: str) -> str:
    """argparse type: the path of an existing file."""
    if not Path(text).is_file():
        raise argparse.ArgumentTypeError(f"no such file: {text!r}")
    return text


#: How --platform tells a shipped platform's name from a config file's path (load_platform's rule).
PLATFORM_RULE = "a name has no / and no .yaml or .yml suffix, whatever the working directory holds"


def platform_name(text: str) -> str:
    """argparse type: a shipped platform's name or a platform YAML file that loads."""
    from stewart_env.params import load_platform

    try:
        load_platform(text)
    except (ValueError, OSError, KeyError, TypeError) as err:
        raise argparse.ArgumentTypeError(str(err)) from None
    return text


def model_name(text: str) -> str:
    """argparse type: a dynamics model name (classical, improved, ... with +c1..+c4 switches)."""
    from stewart_env.dynamics.model import parse_model_name

    try:
        return parse_model_name(text)[0]
    except ValueError as err:
        raise argparse.ArgumentTypeError(str(err)) from None


def plant_model_name(text: str) -> str:
    """argparse type: a value of the environment's ``model`` argument: a dynamics model name (see
    :func:`model_name`) or ``"mujoco"``, MuJoCo's simulation of the same mechanism (a plant only:
    it has no closed-form dynamics for a controller to use); the environment's configuration
    checks it (:func:`stewart_env.envs.config.model_argument`)."""
    from stewart_env.envs.config import model_argument

    try:
        return model_argument(text)
    except ValueError as err:
        raise argparse.ArgumentTypeError(str(err)) from None


def env_kwargs_token(text: str) -> str:
    """argparse type of one --env-kwargs token: checked here, so that a bad one is an argparse error."""
    from stewart_env.agents.training import TrainingError, parse_env_kwargs

    try:
        parse_env_kwargs([text])
    except TrainingError as exc:
        raise argparse.ArgumentTypeError(str(exc).removeprefix("--env-kwargs: ")) from None
    return text


def agent_config(text: str) -> str:
    """argparse type of --config: a hyperparameter file's path, or a shipped config's name
    (``ppo_6m`` or ``ppo_6m.yml``), as the path of that file."""
    from stewart_env.agents.training import TrainingError, config_path

    try:
        return str(config_path("", text))
    except TrainingError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
