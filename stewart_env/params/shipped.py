"""The configs shipped with the package, by name: platforms (``configs/platforms/<name>.yaml``)
and agents' hyperparameters (``configs/agents``), in the installed ``stewart_env.configs``
package or the source tree; and :func:`load_platform`, which takes a name or a path.
"""

from __future__ import annotations

import importlib.resources
import os
from pathlib import Path

from stewart_env.params.checks import ConfigError, describe
from stewart_env.params.platform import PlatformParams, from_text

__all__ = ["config_dir", "available_platforms", "load_platform"]


def config_dir(kind: str) -> Path:
    """The directory of shipped configs of one kind, ``platforms`` or ``agents``: in the installed
    `stewart_env.configs` package, or configs/<kind> in the source tree when the package is not
    installed (running from a checkout)."""
    try:
        installed = importlib.resources.files("stewart_env.configs") / kind
    except ModuleNotFoundError:
        installed = None
    if installed is not None and installed.is_dir():
        return Path(str(installed))
    return Path(__file__).resolve().parents[2] / "configs" / kind


def available_platforms() -> list[str]:
    """Names of the shipped platform configs, sorted."""
    directory = config_dir("platforms")
    if not directory.is_dir():
        return []
    return sorted(entry.name.removesuffix(".yaml") for entry in directory.iterdir()
                  if entry.name.endswith(".yaml"))


def _exists(path: Path) -> bool:
    try:
        return path.exists()
    except (OSError, ValueError):  # a name too long for the file system, a NUL character
        return False


def load_platform(name_or_path: str | os.PathLike) -> PlatformParams:
    """Load a platform by name (a shipped config, see `available_platforms`) or from a YAML file.

    A string without a suffix or directory part that is not an existing path is a name, e.g.
    ``"dasgupta1998"``; anything else (``"my.yaml"``, ``"dir/robot"``, a Path) is read as a file,
    which must be a regular *.yaml or *.yml file of at most MAX_CONFIG_BYTES (see
    `PlatformParams.from_yaml`).

    Args:
        name_or_path: a shipped platform's name, or the path of a YAML config.

    Returns:
        The platform's validated :class:`PlatformParams`.

    Raises:
        ConfigError: an unknown name, or a file that cannot be read or is not a valid config
            (the message names the file or the key).

    Examples:
        >>> import stewart_env as se
        >>> params = se.load_platform("dasgupta1998")
        >>> params.name, params.home_position.tolist()
        ('dasgupta1998', [0.0, 0.0, 0.4])
    """
    # a bytes path (or a PathLike giving one) is refused too: names and messages are text
    text = os.fspath(name_or_path) if isinstance(name_or_path, (str, os.PathLike)) else None
    if not isinstance(text, str):
        raise ConfigError("", f"expected a platform name or a path, got {describe(name_or_path)}")
    candidate = Path(text)
    is_name = (isinstance(name_or_path, str) and not candidate.suffix and candidate.name == text
               and not _exists(candidate))
    if not is_name:
        return PlatformParams.from_yaml(candidate)
    if text not in available_platforms():
        available = ", ".join(available_platforms()) or "none"
        raise ConfigError("", f"unknown platform {describe(text)}; available: {available}")
    resource = config_dir("platforms") / f"{text}.yaml"
    return from_text(resource.read_text(encoding="utf-8"), text, f"{text}.yaml")
