"""What the verbs share: the one-line error, the checks made before any work and the baseline
controllers by name.

A usage error that names its argument as data (:attr:`stewart_env.errors.UsageError.argument`) is
said of the flag that sets the argument (:data:`FLAGS`), as argparse says its own errors:
``stewart-env <verb>: error: argument --model: unknown model 'newton'; ...``."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterable, Sequence
from typing import TYPE_CHECKING

from stewart_env.errors import UsageError
from stewart_env.extras import require

if TYPE_CHECKING:
    from stewart_env.dynamics import ModelSpec

#: The baseline controllers ``--policy`` offers.
CONTROLLERS = ("pd", "pd-gc", "ct", "lqr", "mpc")


#: The command-line flag of each argument a usage error may name: the keyword of the library call
#: (the environment's, a study's or an identification's setting) -> the option that sets it.
FLAGS = {
    "model": "--model",
    "plant": "--plant",
    "internal_model": "--internal-model",
    "cost_plant": "--cost-plant",
    "platform": "--platform",
    "controller_platforms": "--controller-platform",
    "controllers": "--controllers",
    "env_kwargs": "--env-kwargs",
    "out": "--out",
    "config": "--config",
    "excitation": "--excitation",
    "derivatives": "--derivatives",
    "duration": "--duration",
    "period": "--period",
    "noise_position": "--noise-position",
    "noise_angle": "--noise-angle",
    "noise_force": "--noise-force",
    "delay": "--delay",
    "perturb": "--perturb",
    "max_iterations": "--iterations",
    "timestep": "--timestep",
    "solref": "--solref",
    "solimp": "--solimp",
}


def usage_message(err: object) -> str:
    """The one-line message of ``err``: ``argument --flag: <problem>`` for a usage error about an
    argument a flag sets (:data:`FLAGS`), else the error's own message.

    Args:
        err: the error (or message) to say.
    """
    flag = FLAGS.get(err.argument) if isinstance(err, UsageError) and err.argument else None
    return f"argument {flag}: {err.problem}" if flag else str(err)


def error(verb: str, message: object) -> int:
    """Print ``stewart-env <verb>: error: <message>`` to stderr (a usage error as
    :func:`usage_message` says it); the exit status of a usage error, 2.

    Args:
        verb: the command, e.g. ``train``.
        message: the error or its text.
    """
    print(f"stewart-env {verb}: error: {usage_message(message)}", file=sys.stderr)
    return 2


def check_out(args: argparse.Namespace) -> str | None:
    """Why ``--out`` cannot be written (None if it can), before any work is done.

    Args:
        args: the parsed command line; without an ``out`` there is nothing to check.
    """
    from stewart_env.files import check_writable

    if getattr(args, "out", None) is None:
        return None
    try:
        check_writable(args.out, create=False)
    except ValueError as err:  # stewart_env.files.NotWritable
        return f"argument --out: {err}"
    return None


def check_extras(needs: Iterable[tuple[str, str]]) -> str | None:
    """The first missing extra of ``needs`` ((extra, what needs it), ...) as its one-line message.

    Args:
        needs: (extra, what needs it) pairs, e.g. ``("mujoco", "--mujoco")``.
    """
    for extra, what in needs:
        try:
            require(extra, what)
        except ValueError as err:  # stewart_env.extras.MissingExtra
            return str(err)
    return None


def plant_extras(models: Sequence[ModelSpec | str] | None, flag: str = "--model") -> list[tuple[str, str]]:
    """The extra a plant of ``models`` needs: MuJoCo's plant needs ``mujoco``.

    Args:
        models: the plants, each a model's spec or ``"mujoco"`` (None: the default plant).
        flag: the flag that names them, which the message gives.
    """
    return [("mujoco", f"{flag} mujoco")] if models and "mujoco" in models else []


def controllers(names: Sequence[str], internal_model: ModelSpec) -> dict:
    """{table label: policy factory} of the baseline controllers ``names`` (see :data:`CONTROLLERS`).

    Args:
        names: the controllers' names (``pd``, ``pd-gc``, ``ct``, ``lqr``, ``mpc``).
        internal_model: the spec of the dynamics model computed torque, the LQR and the MPC use.
    """
    from stewart_env.agents.controllers.computed_torque import ComputedTorquePolicy
    from stewart_env.agents.controllers.lqr import LQRPolicy
    from stewart_env.agents.controllers.mpc import MPCPolicy
    from stewart_env.agents.controllers.pd import PDPolicy

    out = {}
    for name in names:
        if name == "pd":
            out["PD"] = PDPolicy
        elif name == "pd-gc":
            out["PD + gravity comp."] = lambda env: PDPolicy(env, gravity_compensation=True)
        elif name == "lqr":
            out[f"LQR ({internal_model})"] = lambda env, m=internal_model: LQRPolicy(env, m)
        elif name == "mpc":
            out[f"MPC ({internal_model})"] = lambda env, m=internal_model: MPCPolicy(env, m)
        else:
            out[f"CT ({internal_model})"] = lambda env, m=internal_model: ComputedTorquePolicy(env, m)
    return out
