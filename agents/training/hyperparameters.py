"""The hyperparameters: rl-baselines3-zoo's YAML format, read and split as rl_zoo3 splits it.

Hyperparameters come from ``configs/agents/<algo>.yml`` in rl-baselines3-zoo's format,
keyed by the environment id, so the same files drive ``python -m rl_zoo3.train``.  The file is
read with the package's bounded reader of regular files (:func:`stewart_env.files.read_regular`) and
decoder of YAML (:func:`stewart_env.files.load_yaml`).
The zoo's string-valued entries (``policy_kwargs: "dict(net_arch=[64, 64])"``) are read by a
parser of that vocabulary (:func:`zoo_eval`), never evaluated as Python.
"""

from __future__ import annotations

import ast
import inspect
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from stewart_env.agents.training.errors import TrainingError, check_rl_installed
from stewart_env.errors import UsageError
from stewart_env.files import DocumentError, load_yaml, read_regular
from stewart_env.params import MAX_CONFIG_BYTES, config_dir
from stewart_env.params.checks import excerpt
from stewart_env.params.shipped import is_shipped_name
from stewart_env.registration import ENV_ID
from stewart_env.validation import integer

__all__ = [
    "ACTIVATIONS",
    "ALGORITHMS",
    "ALGORITHM_NAMES",
    "CONFIG_DIR",
    "CONTRIB",
    "MAX_COUNT",
    "OFF_POLICY",
    "VEC_ENV_WRAPPERS",
    "ZOO_EVALUATED_KEYS",
    "ZOO_KEYS_HANDLED",
    "ZOO_KEYS_ZOO_ONLY",
    "ZOO_SCHEDULE_KEYS",
    "Hyperparameters",
    "algorithm_class",
    "check_count",
    "check_hyperparameter_names",
    "config_path",
    "parse_hyperparameters",
    "read_hyperparameters",
    "shipped_configs",
    "vec_env_wrappers",
    "zoo_eval",
]

ALGORITHMS = ("ppo", "sac", "td3", "tqc", "crossq")
OFF_POLICY = ("sac", "td3", "tqc", "crossq")
#: The algorithms of sb3-contrib (the rest are stable-baselines3's).
CONTRIB = ("tqc", "crossq")
#: Each algorithm's name as its library spells it (the class name), for labels.
ALGORITHM_NAMES = {"ppo": "PPO", "sac": "SAC", "td3": "TD3", "tqc": "TQC", "crossq": "CrossQ"}
#: Where the zoo-format hyperparameter files live: configs/agents, shipped as stewart_env.configs.
CONFIG_DIR = config_dir("agents")

#: Keys of a zoo hyperparameter entry that are not constructor arguments of the algorithm.
#: rl_zoo3 consumes them itself; ``stewart-env train`` handles the first group and refuses the
#: second with a pointer to rl_zoo3.
ZOO_KEYS_HANDLED = (
    "n_timesteps",
    "policy",
    "normalize",
    "n_envs",
    "env_kwargs",
    "noise_type",
    "noise_std",
    "vec_env_wrapper",
)
ZOO_KEYS_ZOO_ONLY = ("frame_stack", "env_wrapper", "callback", "monitor_kwargs")
#: The vector-environment wrappers a config may name under ``vec_env_wrapper``, by the dotted path
#: rl_zoo3 imports: the package's own only, so that a config names no other code to run.
VEC_ENV_WRAPPERS = (
    "stewart_env.agents.training.action_rate.ActionRatePenalty",
    "stewart_env.agents.training.precision.PrecisionReward",
)
#: Zoo keys whose string value is a Python expression to rl_zoo3; here, data in that syntax.
ZOO_EVALUATED_KEYS = ("policy_kwargs", "replay_buffer_class", "replay_buffer_kwargs")
#: Zoo keys that accept a schedule string "lin_<initial value>".
ZOO_SCHEDULE_KEYS = ("learning_rate", "clip_range", "clip_range_vf")
#: The torch.nn activation classes a config may name, as ``nn.<Name>`` or ``th.nn.<Name>``.
ACTIVATIONS = ("ReLU", "Tanh", "ELU", "LeakyReLU", "GELU", "SiLU", "SELU", "Sigmoid", "Softplus", "Mish")


#: Bound of every count (steps, platforms, checkpoints): SB3 keeps its step counters in int64.
MAX_COUNT = 2**62


def algorithm_class(algo: str):
    """The stable-baselines3 class of ``algo`` (one of :data:`ALGORITHMS`).

    Args:
        algo: the algorithm's name, one of :data:`ALGORITHMS`.
    """
    if algo not in ALGORITHMS:
        raise TrainingError(f"unknown algorithm {algo!r}; choose one of {', '.join(ALGORITHMS)}")
    check_rl_installed()
    import importlib

    library = importlib.import_module("sb3_contrib" if algo in CONTRIB else "stable_baselines3")
    return getattr(library, ALGORITHM_NAMES[algo])


def shipped_configs() -> list[str]:
    """The names of the hyperparameter files shipped with the package (configs/agents)."""
    return sorted(path.stem for path in CONFIG_DIR.glob("*.yml"))


def config_path(algo: str, config: str | os.PathLike | None = None) -> Path:
    """The hyperparameter file of ``algo``: ``config`` if given, else configs/agents/<algo>.yml.

    ``config`` is a shipped config's name (``ppo_6m``: no path separator and no YAML suffix,
    whatever the working directory holds, the rule of platforms), or a file's path; a name with
    the suffix (``ppo_6m.yml``) is the file of that name in the working directory if there is one,
    else the shipped config.

    Args:
        algo: the algorithm's name, one of :data:`ALGORITHMS`.
        config: a shipped config's name or a file's path (default configs/agents/<algo>.yml).
    """
    if config is None:
        return CONFIG_DIR / f"{algo}.yml"
    path = Path(config)
    if is_shipped_name(config):
        shipped = CONFIG_DIR / f"{path.name}.yml"
        if shipped.is_file():
            return shipped
        raise TrainingError(
            f"unknown shipped config {str(config)!r}; shipped: {', '.join(shipped_configs())} (a "
            "file's path has a / or ends in .yml or .yaml)"
        )
    if path.is_file():
        return path
    if len(path.parts) == 1 and not os.path.lexists(path):
        shipped = CONFIG_DIR / (path.name if path.suffix in (".yml", ".yaml") else f"{path.name}.yml")
        if shipped.is_file():
            return shipped
    raise TrainingError(
        f"hyperparameter file not found: {path} (neither a file nor a shipped config: {', '.join(shipped_configs())})"
    )


def read_hyperparameters(algo: str, config: str | os.PathLike | None = None, env_id: str = ENV_ID) -> dict[str, Any]:
    """The raw zoo entry for ``env_id`` in the hyperparameter file of ``algo`` (a copy).

    Args:
        algo: the algorithm's name, one of :data:`ALGORITHMS`.
        config: the hyperparameter file, as :func:`config_path` reads it.
        env_id: the environment whose entry is read.
    """
    path = config_path(algo, config)
    try:
        entries = load_yaml(read_regular(path, MAX_CONFIG_BYTES, "config file"))
    except DocumentError as exc:
        raise TrainingError(f"{path}: {exc.problem}") from None
    if not isinstance(entries, dict) or env_id not in entries:
        found = ", ".join(map(str, entries)) if isinstance(entries, dict) else ""
        raise TrainingError(f"{path}: no entry for {env_id!r} (found: {found or 'nothing'})")
    entry = entries[env_id]
    if not isinstance(entry, dict):
        raise TrainingError(f"{path}: the entry for {env_id!r} must be a mapping of hyperparameters")
    return dict(entry)


def _describe(node: ast.AST) -> str:
    """What a refused piece of a zoo expression is, for the error message."""
    if isinstance(node, ast.Call):
        return f"the call {ast.unparse(node.func)}(...)"
    if isinstance(node, (ast.Attribute, ast.Name)):
        return f"the name {ast.unparse(node)}"
    if isinstance(node, ast.Lambda):
        return "a lambda"
    if isinstance(node, (ast.ListComp, ast.SetComp, ast.DictComp, ast.GeneratorExp)):
        return "a comprehension"
    if isinstance(node, ast.Constant):
        return f"the constant {node.value!r}"
    return f"the expression {ast.unparse(node)!r}"


def _zoo_value(node: ast.AST, key: str, text: str) -> Any:
    """The data of one node of a zoo expression; TrainingError naming ``key`` for anything else."""
    if isinstance(node, ast.Constant) and (node.value is None or type(node.value) in (bool, int, float, str)):
        return node.value
    if (
        isinstance(node, ast.UnaryOp)
        and isinstance(node.op, (ast.USub, ast.UAdd))
        and isinstance(node.operand, ast.Constant)
        and type(node.operand.value) in (int, float)
    ):
        return -node.operand.value if isinstance(node.op, ast.USub) else node.operand.value
    if isinstance(node, (ast.List, ast.Tuple)):
        items = [_zoo_value(e, key, text) for e in node.elts]
        return items if isinstance(node, ast.List) else tuple(items)
    if isinstance(node, ast.Dict) and None not in node.keys:  # a None key is a ** unpacking
        keys = [_zoo_value(k, key, text) for k in node.keys]
        if not all(isinstance(k, (str, int, float, bool)) or k is None for k in keys):
            raise TrainingError(f"hyperparameter {key}: dict keys must be names or numbers in {text!r}")
        return dict(zip(keys, (_zoo_value(v, key, text) for v in node.values)))
    if (
        isinstance(node, ast.Call)
        and isinstance(node.func, ast.Name)
        and node.func.id == "dict"
        and not node.args
        and all(k.arg is not None for k in node.keywords)
    ):
        return {k.arg: _zoo_value(k.value, key, text) for k in node.keywords}
    if isinstance(node, ast.Attribute):
        dotted = ast.unparse(node)
        if dotted in {f"{prefix}.{name}" for prefix in ("nn", "th.nn") for name in ACTIVATIONS}:
            import torch

            return getattr(torch.nn, node.attr)
    raise TrainingError(
        f"hyperparameter {key}: {_describe(node)} is not allowed in {text!r}; a config holds data "
        "only: dict(key=value, ...), {...}, [...], (...), numbers, strings, True/False/None and "
        f"nn.<activation> ({', '.join(ACTIVATIONS)})"
    )


def zoo_eval(text: str, key: str) -> Any:
    """Read a zoo hyperparameter string (e.g. ``policy_kwargs: "dict(net_arch=[64, 64])"``) as
    data: the subset of Python that rl-zoo configs use (see :func:`_zoo_value`), parsed, never
    evaluated, so that a config from a stranger cannot run code.

    Args:
        text: the string's text.
        key: the hyperparameter's name, which the error names.
    """
    try:
        tree = ast.parse(text.strip(), mode="eval")
        return _zoo_value(tree.body, key, text)
    except SyntaxError as exc:
        raise TrainingError(f"hyperparameter {key}: not an expression: {excerpt(text)!r} ({exc.msg})") from None
    except (RecursionError, MemoryError):  # Python's parser gives out on a chain of thousands of operators
        raise TrainingError(f"hyperparameter {key}: not an expression: {excerpt(text)!r} (nested too deeply)") from None


def _schedule(value: Any, key: str):
    """A zoo schedule ("lin_<x>": linear from x to 0 over training) or a constant, as SB3 takes it."""
    if isinstance(value, str):
        kind, _, initial = value.partition("_")
        try:
            start = float(initial)
        except ValueError:
            start = None
        if kind != "lin" or start is None:
            raise TrainingError(f"hyperparameter {key}: expected a number or 'lin_<number>', got {value!r}")
        from stable_baselines3.common.utils import LinearSchedule

        return LinearSchedule(start, 0.0, 1.0)
    return value


@dataclass
class Hyperparameters:
    """A zoo entry split the way rl_zoo3 splits it.

    algorithm_kwargs go to the algorithm's constructor (policy included); n_envs rows of the
    native batch; n_timesteps the default budget; normalize the VecNormalize keyword arguments
    (None: no normalisation); env_kwargs the entry's environment keyword arguments;
    vec_env_wrappers the training batch's wrappers (``vec_env_wrapper``), each a class and its
    keyword arguments, applied in order between VecMonitor and VecNormalize.
    """

    algorithm_kwargs: dict[str, Any]
    n_envs: int
    n_timesteps: int
    normalize: dict[str, Any] | None
    env_kwargs: dict[str, Any]
    raw: dict[str, Any]
    vec_env_wrappers: tuple[tuple[type, dict[str, Any]], ...] = ()


def check_hyperparameter_names(algo: str, entry: Mapping[str, Any]) -> None:
    """Refuse keys that are neither zoo keys nor constructor arguments of the algorithm.

    Args:
        algo: the algorithm's name, one of :data:`ALGORITHMS`.
        entry: the zoo entry.
    """
    cls = algorithm_class(algo)
    valid = set(inspect.signature(cls.__init__).parameters) - {"self", "env"}
    zoo = set(ZOO_KEYS_HANDLED) | set(ZOO_KEYS_ZOO_ONLY)
    unknown = sorted(k for k in entry if k not in valid and k not in zoo)
    if unknown:
        raise TrainingError(
            f"{algo}: unknown hyperparameter(s) {', '.join(unknown)}; valid: {', '.join(sorted(valid | zoo))}"
        )


def parse_hyperparameters(algo: str, entry: Mapping[str, Any]) -> Hyperparameters:
    """Turn a zoo entry into SB3 arguments, as rl_zoo3's ExperimentManager does.

    Args:
        algo: the algorithm's name, one of :data:`ALGORITHMS`.
        entry: the zoo entry (of :func:`read_hyperparameters`).
    """
    check_hyperparameter_names(algo, entry)
    zoo_only = [k for k in ZOO_KEYS_ZOO_ONLY if k in entry]
    if zoo_only:
        raise TrainingError(
            f"{algo}: hyperparameter(s) {', '.join(zoo_only)} are handled by rl_zoo3 only; "
            "train with `python -m rl_zoo3.train` or remove them"
        )
    kwargs = {k: v for k, v in entry.items() if k not in ZOO_KEYS_HANDLED}
    kwargs["policy"] = entry.get("policy", "MlpPolicy")
    for key in ZOO_EVALUATED_KEYS:
        if isinstance(kwargs.get(key), str):
            kwargs[key] = zoo_eval(kwargs[key], key)
    for key in ZOO_SCHEDULE_KEYS:
        if key in kwargs:
            kwargs[key] = _schedule(kwargs[key], key)
    if isinstance(kwargs.get("train_freq"), list):
        kwargs["train_freq"] = tuple(kwargs["train_freq"])
    if entry.get("noise_type") is not None:
        from stable_baselines3.common.noise import NormalActionNoise, OrnsteinUhlenbeckActionNoise

        noise = {"normal": NormalActionNoise, "ornstein-uhlenbeck": OrnsteinUhlenbeckActionNoise}
        kind = str(entry["noise_type"]).strip()
        if kind not in noise:
            raise TrainingError(f"{algo}: noise_type must be one of {', '.join(noise)}, got {kind!r}")
        std = float(entry.get("noise_std", 0.1))
        kwargs["action_noise"] = noise[kind](mean=np.zeros(6), sigma=std * np.ones(6))

    normalize = entry.get("normalize", False)
    if isinstance(normalize, str):
        normalize = zoo_eval(normalize, "normalize")
    if normalize is True:
        normalize = {}
    elif normalize is False:
        normalize = None
    elif not isinstance(normalize, dict):
        raise TrainingError(f"{algo}: normalize must be true, false or a dict (or its string), got {normalize!r}")
    if normalize is not None and "gamma" in entry:
        normalize = {**normalize, "gamma": entry["gamma"]}  # as the zoo: discount the reward as the agent does

    n_envs = entry.get("n_envs", 1)
    check_count(f"{algo}: n_envs", n_envs, 1)
    if "n_timesteps" not in entry:
        raise TrainingError(f"{algo}: the entry has no n_timesteps")
    env_kwargs = entry.get("env_kwargs") or {}
    if not isinstance(env_kwargs, dict):
        raise TrainingError(f"{algo}: env_kwargs must be a mapping, got {env_kwargs!r}")
    wrappers = vec_env_wrappers(entry.get("vec_env_wrapper"))
    return Hyperparameters(
        kwargs, n_envs, int(float(entry["n_timesteps"])), normalize, dict(env_kwargs), dict(entry), wrappers
    )


def vec_env_wrappers(value: Any) -> tuple[tuple[type, dict[str, Any]], ...]:
    """The wrappers of a zoo entry's ``vec_env_wrapper``, in rl_zoo3's forms: a dotted class path,
    a one-key mapping of a path to its keyword arguments, or a list of these; each one of
    :data:`VEC_ENV_WRAPPERS`, its keyword arguments checked by the class's ``check_options``.

    Args:
        value: the entry's ``vec_env_wrapper`` (None: no wrapper).

    Returns:
        Each wrapper's class and keyword arguments, in order.

    Raises:
        TrainingError: a form, class or keyword argument the entry may not give (the message names
            ``vec_env_wrapper``).
    """
    import importlib

    wrappers = []
    for item in [] if value is None else value if isinstance(value, list) else [value]:
        if isinstance(item, dict) and len(item) == 1:
            name, options = next(iter(item.items()))
            options = {} if options is None else options
        else:
            name, options = item, {}
        if not isinstance(name, str) or not isinstance(options, dict):
            raise TrainingError(
                f"hyperparameter vec_env_wrapper: expected a class path or a mapping of one class path "
                f"to its keyword arguments, got {excerpt(repr(item))}"
            )
        if name not in VEC_ENV_WRAPPERS:
            raise TrainingError(
                f"hyperparameter vec_env_wrapper: {excerpt(name)!r} is not a wrapper stewart-env trains with; "
                f"choose {', '.join(VEC_ENV_WRAPPERS)} (or train with `python -m rl_zoo3.train`)"
            )
        module, _, class_name = name.rpartition(".")
        cls = getattr(importlib.import_module(module), class_name)
        valid = set(inspect.signature(cls.check_options).parameters)
        unknown = sorted(map(str, set(options) - valid))
        if unknown:
            raise TrainingError(
                f"hyperparameter vec_env_wrapper: {class_name}: unknown keyword argument(s) {', '.join(unknown)}; "
                f"valid: {', '.join(sorted(valid))}"
            )
        try:
            cls.check_options(**options)
        except UsageError as err:
            raise TrainingError(
                f"hyperparameter vec_env_wrapper: {class_name}: {err}", argument="vec_env_wrapper", problem=err.problem
            ) from None
        wrappers.append((cls, dict(options)))
    return tuple(wrappers)


def check_count(name: str, value: Any, minimum: int, maximum: int = MAX_COUNT) -> None:
    """A count of steps, platforms or checkpoints, through the package's one integer check.

    Args:
        name: the argument's name, which the error gives.
        value: the count.
        minimum: the smallest count accepted.
        maximum: the largest.
    """
    try:
        integer(name, value, minimum, maximum)
    except UsageError as err:
        raise TrainingError(str(err), argument=err.argument, problem=err.problem) from None
