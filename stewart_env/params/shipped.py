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
from stewart_env.params.reader import CONFIG_SUFFIXES

__all__ = ["config_dir", "available_platforms", "is_platform_name", "is_shipped_name", "load_platform"]


def config_dir(kind: str) -> Path:
    """The directory of shipped configs of one kind, ``platforms`` or ``agents``: in the installed
    `stewart_env.configs` package, or configs/<kind> in the source tree when the package is not
    installed (running from a checkout).

    Args:
        kind: ``"platforms"`` or ``"agents"``.
    """
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
    return sorted(entry.name.removesuffix(".yaml") for entry in directory.iterdir() if entry.name.endswith(".yaml"))


def is_shipped_name(name_or_path: object) -> bool:
    """Whether ``name_or_path`` names a shipped config (a platform, an agent's hyperparameters)
    rather than a file.

    A string with no path separator (``/``, or the system's own) and no ``.yaml``/``.yml``
    suffix is a shipped config's name, whatever the working directory holds (a folder left by
    ``--out dasgupta1998`` does not hide the shipped platform); anything else, a string with a
    separator or a YAML suffix or a ``Path``, is a file.

    Args:
        name_or_path: what :func:`load_platform` was given.

    Returns:
        True for a name, False for a file.
    """
    if not isinstance(name_or_path, str):
        return False
    separators = {"/", os.sep} | ({os.altsep} if os.altsep else set())
    return not any(sep in name_or_path for sep in separators) and not name_or_path.lower().endswith(CONFIG_SUFFIXES)


#: The rule of :func:`is_shipped_name`, for platforms.
is_platform_name = is_shipped_name


def load_platform(name_or_path: str | os.PathLike) -> PlatformParams:
    """Load a platform by name (a shipped config, see `available_platforms`) or from a YAML file.

    A string with no path separator and no ``.yaml``/``.yml`` suffix is always a shipped
    platform's name, e.g. ``"dasgupta1998"``, whatever the working directory holds (a folder or
    file named ``dasgupta1998`` there is not read); anything with a separator or a YAML suffix
    (``"./dasgupta1998.yaml"``, ``"dir/robot.yaml"``, ``"robot.yml"``), or a ``Path``, is read
    as a file, which must be a regular *.yaml or *.yml file of at most MAX_CONFIG_BYTES (see
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
    if not is_platform_name(name_or_path):
        if not text.lower().endswith(CONFIG_SUFFIXES):  # named as given: "./dasgupta1998", not "dasgupta1998"
            names = ", ".join(available_platforms()) or "none"
            raise ConfigError(
                "",
                f"not a platform config: a config file's name ends in .yaml or .yml; a shipped "
                f"platform is named by a string alone, with no path ({names})",
                text,
            )
        return PlatformParams.from_yaml(Path(text))
    if text not in available_platforms():
        available = ", ".join(available_platforms()) or "none"
        raise ConfigError(
            "",
            f"unknown platform {describe(text)}; available: {available} (a config file's path "
            "has a / or ends in .yaml or .yml)",
        )
    resource = config_dir("platforms") / f"{text}.yaml"
    return from_text(resource.read_text(encoding="utf-8"), text, f"{text}.yaml")
