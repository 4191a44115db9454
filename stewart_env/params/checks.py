"""Raw config values (numbers, nested lists, numpy arrays, mappings) checked and turned into float64
values, and :class:`ConfigError`, the error that names the offending key.

Every number must be a real number (not a boolean), finite as a float64 and at most
:data:`MAX_MAGNITUDE` in magnitude. Messages quote at most a short excerpt of a value, never a
whole file: a config may come from anywhere, e.g. a file of secrets given by mistake.
"""

from __future__ import annotations

import math
import re
import reprlib
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager

import numpy as np

from stewart_env.errors import UsageError

__all__ = [
    "ConfigError",
    "within",
    "MAX_MAGNITUDE",
    "EXCERPT",
    "excerpt",
    "short",
    "describe",
    "kind",
    "key_names",
    "number",
    "array",
    "interval",
    "mapping",
    "frozen_array",
    "is_sequence",
]

# No physical value of a Stewart platform in SI units comes near 1e12; products of a few such
# values in the dynamics stay far from float64's 1.8e308.
MAX_MAGNITUDE = 1e12
#: Longest excerpt of a value quoted in an error message, characters.
EXCERPT = 60


class ConfigError(UsageError):
    """An invalid platform parameter or config file (also raised for an invalid domain
    randomisation spec).

    Attributes:
        key: path of the offending value in the config, e.g. ``"platform.inertia"`` or
            ``"hooke_axes[3]"``; empty for problems of the config or file as a whole.
        problem: what is wrong with it.
        source: the file the config came from, if any.
        argument: the key again, as every usage error names its argument (None for the whole
            config).
    """

    def __init__(self, key: str, problem: str, source: str | None = None):
        super().__init__(key, problem, source, argument=key or None, problem=problem)
        self.key = key
        self.problem = problem
        self.source = source

    def __str__(self) -> str:
        text = f"{self.key}: {self.problem}" if self.key else self.problem
        return f"{self.source}: {text}" if self.source else text

    def within(self, prefix: str) -> ConfigError:
        """The same error, its key moved under `prefix` (``"inertia"`` -> ``"platform.inertia"``).

        Args:
            prefix: the key path to put in front, e.g. ``"platform"``.
        """
        if not self.key:
            key = prefix
        elif self.key.startswith("["):
            key = prefix + self.key
        else:
            key = f"{prefix}.{self.key}"
        return ConfigError(key, self.problem, self.source)


@contextmanager
def within(prefix: str) -> Iterator[None]:
    """Re-raise a ConfigError from the block with its key path under `prefix`.

    Args:
        prefix: the key path to put in front, e.g. ``"platform"``.
    """
    try:
        yield
    except ConfigError as err:
        raise err.within(prefix) from None


# ----------------------------------------------------------------------------------------------
# Short descriptions of values for error messages.


# PyYAML (YAML 1.1) reads exponent floats without a dot, such as 1e-4, as text.
_TEXT_HINT = " (text; in YAML write floats with a dot, e.g. 1.0e-4)"


def excerpt(text: str, limit: int = EXCERPT) -> str:
    """`text` cut to `limit` characters, an ellipsis marking the cut.

    Args:
        text: the text.
        limit: the most characters kept, the ellipsis included.
    """
    return text if len(text) <= limit else text[: limit - 3] + "..."


class _ShortRepr(reprlib.Repr):
    """repr() that stays short however large or deeply nested the value is (a YAML file can
    expand to a huge structure): a few items per level, a few levels."""

    def __init__(self) -> None:
        super().__init__()
        self.maxlevel = 3
        self.maxlist = self.maxtuple = self.maxdict = self.maxset = self.maxfrozenset = 4
        self.maxstring = self.maxlong = self.maxother = EXCERPT

    def repr_int(self, x: int, level: int) -> str:
        try:
            return super().repr_int(x, level)
        except ValueError:  # str() refuses integers of more than sys.get_int_max_str_digits()
            return f"an integer of about {int(x.bit_length() * math.log10(2))} digits"


_short_repr = _ShortRepr()


def short(value: object) -> str:
    """A short excerpt of `value`'s repr for an error message.

    Args:
        value: the value, as read from a config.
    """
    try:
        return excerpt(_short_repr.repr(value))
    except Exception:  # a foreign object whose repr fails: name its type instead
        return f"a {type(value).__name__}"


def describe(value: object) -> str:
    """`short(value)`, with a hint when it is a number that YAML read as text.

    Args:
        value: the value, as read from a config.
    """
    return short(value) + (_TEXT_HINT if isinstance(value, str) and _is_float_text(value) else "")


def _is_float_text(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def kind(value: object) -> str:
    """What `value` is, without quoting it.

    Args:
        value: the value, as read from a config.
    """
    if value is None:
        return "None"
    if isinstance(value, str):
        return f"text of {len(value)} characters"
    if is_sequence(value):
        return f"a {type(value).__name__} of {len(value)} items"
    name = type(value).__name__
    return f"{'an' if name[0] in 'aeiou' else 'a'} {name}"


_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_.]{0,39}")  # dotted too: randomisation keys ("legs.mass")


def key_names(keys: Sequence) -> str:
    """Unknown keys for an error message, the first three of them: quoted if they look like
    misspelt names, else only described, for a file that is no config at all may be all keys (a
    line of /etc/shadow is a YAML key).

    Args:
        keys: the unknown keys, in the file's order.
    """
    names = [repr(k) if isinstance(k, str) and _NAME.fullmatch(k) else f"({kind(k)})" for k in keys[:3]]
    return ", ".join(names) + (f" and {len(keys) - 3} more" if len(keys) > 3 else "")


# ----------------------------------------------------------------------------------------------
# Coercion of raw values into checked float64 values.


def number(value: object, key: str) -> float:
    """A finite float of magnitude at most MAX_MAGNITUDE. Booleans and strings are refused:
    they are always a mistake here.

    Args:
        value: the raw value.
        key: the value's key path in the config, which the error names, e.g. ``platform.mass``.
    """
    numeric = isinstance(value, (int, float, np.integer, np.floating))
    if isinstance(value, (bool, np.bool_)) or not numeric:
        raise ConfigError(key, f"must be a number, got {describe(value)}")
    try:
        result = float(value)
    except OverflowError:  # an int beyond float64's range
        result = math.inf
    if not math.isfinite(result):
        raise ConfigError(key, f"not a finite number ({describe(value if isinstance(value, int) else result)})")
    if abs(result) > MAX_MAGNITUDE:
        raise ConfigError(key, f"magnitude above {MAX_MAGNITUDE:g}, got {result:g}")
    return result


def frozen_array(values: np.ndarray) -> np.ndarray:
    """A float64 copy whose memory belongs to an immutable bytes object, so that nobody can turn
    its WRITEABLE flag back on.

    Args:
        values: the numbers.
    """
    data = np.ascontiguousarray(values, dtype=np.float64)
    return np.frombuffer(data.tobytes(), dtype=np.float64).reshape(data.shape)


def is_sequence(value: object) -> bool:
    """A list, tuple or numpy array (not text).

    Args:
        value: the value.
    """
    return isinstance(value, (Sequence, np.ndarray)) and not isinstance(value, (str, bytes))


def array(value: object, key: str, *shapes: tuple[int, ...]) -> np.ndarray:
    """A float64 array of one of `shapes` (not yet frozen), every entry checked by `number` and
    named by its index path, e.g. ``base_joints[3][1]``.

    Args:
        value: the raw value: nested sequences of numbers or a numeric array.
        key: the value's key path in the config, which the error names, e.g. ``platform.mass``.
        *shapes: the accepted shapes, e.g. ``(6, 3)``.
    """
    expected = " or ".join(str(s) for s in shapes)
    if isinstance(value, np.ndarray) and value.dtype.kind in "iuf":
        if value.shape not in shapes:
            raise ConfigError(key, f"expected shape {expected}, got {value.shape}")
        with np.errstate(over="ignore"):  # an overflowing float128 becomes inf, refused below
            arr = value.astype(np.float64)
        bad = np.argwhere(~(np.abs(arr) <= MAX_MAGNITUDE))
        if bad.size:
            index = tuple(int(i) for i in bad[0])
            number(value[index], key + "".join(f"[{i}]" for i in index))
        return arr
    if isinstance(value, np.ndarray) and value.ndim == 0:
        value = value[()]
    if not is_sequence(value):
        raise ConfigError(key, f"expected numbers of shape {expected}, got {describe(value)}")
    depth = max(len(s) for s in shapes)
    longest = max(max(s) for s in shapes)

    def numbers(item: object, where: str, level: int) -> float | list:
        # Lengths are checked before walking, so a huge or deep list costs nothing.
        if isinstance(item, np.ndarray) and item.ndim == 0:
            item = item[()]
        if not is_sequence(item) or level == depth:
            return number(item, where)
        if len(item) > longest:
            raise ConfigError(where, f"expected shape {expected}, got a sequence of {len(item)} items")
        return [numbers(x, f"{where}[{i}]", level + 1) for i, x in enumerate(item)]

    nested = numbers(value, key, 0)
    try:
        arr = np.array(nested, dtype=np.float64)
    except ValueError:
        raise ConfigError(key, f"expected numbers of shape {expected}, got rows of unequal lengths") from None
    if arr.shape not in shapes:
        raise ConfigError(key, f"expected shape {expected}, got {arr.shape}")
    return arr


def interval(value: object, key: str) -> tuple[float, float]:
    """(min, max) with min < max.

    Args:
        value: the raw value, two numbers.
        key: the value's key path in the config, which the error names, e.g. ``platform.mass``.
    """
    lo, hi = array(value, key, (2,))
    if not lo < hi:
        raise ConfigError(key, f"expected (min, max) with min < max, got ({lo}, {hi})")
    return float(lo), float(hi)


def mapping(value: object, key: str, required: Sequence[str], optional: Sequence[str] = ()) -> Mapping:
    """Check that `value` is a mapping with all `required` keys and nothing unknown.

    Args:
        value: the raw value.
        key: the value's key path in the config, which the error names (empty: the whole document).
        required: the keys it must have.
        optional: the keys it may have besides.
    """
    if not isinstance(value, Mapping):
        # The whole document is never quoted: it may be any file, e.g. one of secrets.
        got = describe(value) if key else kind(value)
        raise ConfigError(key, f"expected a mapping, got {got}")
    # Unknown keys first: a misspelt required key is then reported as the typo it is.
    known = (*required, *optional)
    unknown = [k for k in value if k not in known]
    if unknown:
        raise ConfigError(
            key,
            f"unknown key {key_names(unknown)} (expected " + ", ".join(repr(k) for k in known) + ")",
        )
    missing = [k for k in required if k not in value]
    if missing:
        raise ConfigError(key, "missing key " + ", ".join(repr(k) for k in missing))
    return value
