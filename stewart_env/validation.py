"""The argument checks of the environments and tasks: one set of validators, every error naming
the argument it refuses.

A value of the wrong kind (a bool or a string where a number belongs, an unknown keyword) raises
:class:`ArgumentError`, which is both a ``TypeError`` (as Python raises for a bad call) and a
``ValueError`` (as the environment raises for every bad argument), so callers that catch either
see it.  A value of the right kind outside its range raises
:class:`~stewart_env.errors.UsageError` (a ``ValueError``).  Either error carries the argument's
name as data (``err.argument``) beside the message that names it.  Ranges are finite wherever a
value could otherwise overflow a computation downstream.

The ranges are declared once as constraints (:class:`Interval`, :class:`StrOptions`, in the manner
of scikit-learn's parameter validation): the same object checks a keyword's Python value here and
reads an option's text on the command line (:mod:`stewart_env.cli.arguments`).
"""

from __future__ import annotations

import math
import numbers
import reprlib
from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np

from stewart_env.errors import UsageError

__all__ = [
    "MAX_SEED",
    "ArgumentError",
    "Constraint",
    "Interval",
    "StrOptions",
    "check_action",
    "check_keywords",
    "choice",
    "flag",
    "integer",
    "interval",
    "plain",
    "quoted",
    "real",
    "real_array",
    "reset_options",
    "seed",
    "vector",
]


#: Largest seed: numpy's SeedSequence takes any non-negative int, but the seeds a run records
#: and passes on to outside libraries (SB3, torch, Gymnasium's spaces) must fit 32 bits.
MAX_SEED = 2**32 - 1


class ArgumentError(UsageError, TypeError):
    """An argument of the wrong kind, or an unknown keyword argument (``argument`` names it)."""


def _excerpt(value: Any, limit: int = 80) -> str:
    """A short quote of ``value`` for an error message: a huge number, list or string is cut,
    never quoted whole (reprlib bounds digits and items; an int too long for repr is named)."""
    try:
        text = reprlib.repr(value)
    except ValueError:  # an int beyond Python's digit limit for str()
        text = f"<{type(value).__name__} too large to print>"
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _is_real(value: Any) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))


def _as_float(value: Any) -> float:
    try:
        return float(value)
    except OverflowError:  # a Python int beyond the float range
        return math.inf if value > 0 else -math.inf


def _span(low: float, high: float, low_open: bool) -> str:
    if high == math.inf:
        return f"{'>' if low_open else '>='} {low:g}"
    return f"in {'(' if low_open else '['}{low:g}, {high:g}]"


class Constraint:
    """A declarative constraint on one argument, in the manner of scikit-learn's parameter
    validation (``Interval``, ``StrOptions``): what the argument accepts is said once, and the same
    object checks a Python value (:meth:`check`, the environments' keywords and the configs) and
    reads a command-line value (:meth:`parse`, the argparse types of
    :mod:`stewart_env.cli.arguments`).  Every error names the argument as data
    (:attr:`stewart_env.errors.UsageError.argument`).
    """

    #: How a message says what is accepted, e.g. ``"an integer in [1, 10]"``.
    expected: str = "a value"

    def is_satisfied_by(self, value: Any) -> bool:
        """Whether ``value`` (already of the right kind) is accepted.

        Args:
            value: the value.
        """
        raise NotImplementedError

    def check(self, name: str, value: Any) -> Any:
        """``value`` in checked form.

        Args:
            name: the argument's name, which the error gives (as text and as ``argument``).
            value: the value to check.

        Returns:
            The checked value.

        Raises:
            ArgumentError: a value of the wrong kind.
            UsageError: a value of the right kind that is not accepted.
        """
        raise NotImplementedError

    def parse(self, text: str, name: str = "") -> Any:
        """The value of the command-line text ``text``.

        Args:
            text: the text given.
            name: the argument's name, which the error carries.

        Returns:
            The value.

        Raises:
            UsageError: text that is no accepted value; its ``problem`` says what was expected.
        """
        raise NotImplementedError

    def refuse_text(self, text: str, name: str = "") -> UsageError:
        """The error of command-line text that is no accepted value (not raised).

        Args:
            text: the text given.
            name: the argument's name, which the error carries.
        """
        return UsageError.about(name, f"expected {self.expected}, got {quoted(text)}")


class Interval(Constraint):
    """Numbers of one kind in a range: integers (``numbers.Integral``, never a bool) in [low, high],
    or finite real numbers in [low, high] ((low, high] with ``low_open``).

    Args:
        kind: ``numbers.Integral`` or ``numbers.Real``.
        low: the lower bound.
        high: the upper bound.
        low_open: exclude ``low`` (real numbers only).
        expected: how messages say what is accepted, if not in the bounds' own words (e.g.
            ``"a positive integer"``).

    Examples:
        >>> import numbers
        >>> from stewart_env.validation import Interval
        >>> dt = Interval(numbers.Real, 0, 10, low_open=True)
        >>> dt.expected, dt.check("control_dt", 0.01), dt.parse("0.5", "control_dt")
        ('a finite number in (0, 10]', 0.01, 0.5)
    """

    def __init__(self, kind: type, low: float, high: float, *, low_open: bool = False, expected: str | None = None):
        if kind not in (numbers.Integral, numbers.Real):
            raise TypeError(f"Interval: kind must be numbers.Integral or numbers.Real, got {kind!r}")
        if kind is numbers.Integral and low_open:
            raise TypeError("Interval: an integer interval is closed; raise low by one instead")
        self.kind, self.low, self.high, self.low_open = kind, low, high, low_open
        self._expected = expected

    @property
    def expected(self) -> str:  # said only when refusing: a check that passes formats nothing
        """How a message says what is accepted: ``expected``, else the bounds in words."""
        if self._expected is not None:
            return self._expected
        if self.kind is numbers.Integral:
            return f"an integer in [{self.low}, {self.high}]"
        return f"a finite number {_span(self.low, self.high, self.low_open)}"

    def __repr__(self) -> str:
        return f"Interval({self.kind.__name__}, {self.low!r}, {self.high!r}, low_open={self.low_open})"

    def is_satisfied_by(self, value: Any) -> bool:
        """Whether ``value`` (already of the right kind) is accepted.

        Args:
            value: the value.
        """
        if self.kind is numbers.Integral:
            return self.low <= value <= self.high
        return (
            math.isfinite(value) and (value > self.low if self.low_open else value >= self.low) and value <= self.high
        )

    def check(self, name: str, value: Any) -> Any:
        """``value`` in checked form (:meth:`Constraint.check`).

        Args:
            name: the argument's name, which the error gives (as text and as ``argument``).
            value: the value to check.

        Returns:
            The checked value, an int or a float.

        Raises:
            ArgumentError: a value of the wrong kind.
            UsageError: a value of the right kind that is not accepted.
        """
        if self.kind is numbers.Integral:
            if not isinstance(value, numbers.Integral) or isinstance(value, (bool, np.bool_)):
                raise ArgumentError.about(name, f"expected {self.expected}, got {_excerpt(value)}")
            if not self.is_satisfied_by(value):
                raise UsageError.about(name, f"expected {self.expected}, got {_excerpt(value)}")
            return int(value)
        if not _is_real(value):
            raise ArgumentError.about(name, f"expected {self.expected}, got {_excerpt(value)}")
        x = _as_float(value)
        if not self.is_satisfied_by(x):
            raise UsageError.about(name, f"expected {self.expected}, got {_excerpt(value)}")
        return x

    def parse(self, text: str, name: str = "") -> Any:
        """The value of the command-line text ``text`` (:meth:`Constraint.parse`).

        Args:
            text: the text given.
            name: the argument's name, which the error carries.

        Returns:
            The value, an int or a float.

        Raises:
            UsageError: text that is no accepted value; its ``problem`` says what was expected.
        """
        try:
            value = int(text) if self.kind is numbers.Integral else float(text)
        except (ValueError, OverflowError):
            raise self.refuse_text(text, name) from None
        if not self.is_satisfied_by(value):
            raise self.refuse_text(text, name)
        return value


class StrOptions(Constraint):
    """One of a set of strings.

    Args:
        options: the accepted strings, in the order messages list them.
    """

    def __init__(self, options: Iterable[str]):
        self.options = tuple(options)

    @property
    def expected(self) -> str:
        """How a message says what is accepted: the options, quoted."""
        return f"one of {', '.join(map(repr, self.options))}"

    def __repr__(self) -> str:
        return f"StrOptions({self.options!r})"

    def is_satisfied_by(self, value: Any) -> bool:
        """Whether ``value`` (already of the right kind) is accepted.

        Args:
            value: the value.
        """
        return isinstance(value, str) and value in self.options

    def check(self, name: str, value: Any) -> str:
        """``value`` in checked form (:meth:`Constraint.check`).

        Args:
            name: the argument's name, which the error gives (as text and as ``argument``).
            value: the value to check.

        Returns:
            The checked value, the string.

        Raises:
            ArgumentError: a value of the wrong kind.
            UsageError: a value of the right kind that is not accepted.
        """
        if not self.is_satisfied_by(value):
            raise UsageError.about(name, f"expected {self.expected}, got {_excerpt(value)}")
        return value

    def parse(self, text: str, name: str = "") -> str:
        """The value of the command-line text ``text`` (:meth:`Constraint.parse`).

        Args:
            text: the text given.
            name: the argument's name, which the error carries.

        Returns:
            The value, the string.

        Raises:
            UsageError: text that is no accepted value; its ``problem`` says what was expected.
        """
        if not self.is_satisfied_by(text):
            raise UsageError.about(name, f"unknown {quoted(text)}; choose from {', '.join(self.options)}")
        return text


def quoted(text: str, limit: int = 40) -> str:
    """``repr(text)`` for an error message, cut to ``limit`` characters (a number of a thousand
    digits is not echoed whole).

    Args:
        text: the text.
        limit: the most characters of the repr kept.
    """
    text = repr(text)
    return text if len(text) <= limit else text[: limit - 4] + "...'"


def real(name: str, value: Any, low: float = -math.inf, high: float = math.inf, *, low_open: bool = False) -> float:
    """``value`` as a float: a real number (not a bool), finite, in [low, high]
    (:class:`Interval` of ``numbers.Real``).

    Args:
        name: the argument's name, which the error message gives.
        value: the value to check.
        low: the lower bound.
        high: the upper bound.
        low_open: exclude ``low``: (low, high].

    Returns:
        The float.

    Raises:
        ArgumentError: a value of the wrong kind.
        ValueError: a value outside the range (a UsageError naming ``name``).

    Examples:
        >>> from stewart_env.validation import real
        >>> real("control_dt", 0.01, 0.0, 1.0, low_open=True)
        0.01
        >>> real("control_dt", 0.0, 0.0, 1.0, low_open=True)
        Traceback (most recent call last):
        ...
        stewart_env.errors.UsageError: control_dt: expected a finite number in (0, 1], got 0.0
    """
    return Interval(numbers.Real, low, high, low_open=low_open).check(name, value)


def integer(name: str, value: Any, low: int, high: int) -> int:
    """``value`` as an int: an integer (not a bool) in [low, high] (:class:`Interval` of
    ``numbers.Integral``).

    Args:
        name: the argument's name, which the error message gives.
        value: the value to check.
        low: the lower bound.
        high: the upper bound.

    Returns:
        The int.

    Raises:
        ArgumentError: a value of the wrong kind.
        ValueError: a value outside the range (a UsageError naming ``name``).
    """
    return Interval(numbers.Integral, low, high).check(name, value)


def seed(name: str, value: Any) -> int:
    """``value`` as a seed: an integer (not a bool) in [0, :data:`MAX_SEED`].

    Args:
        name: the argument's name, which the error message gives.
        value: the value to check.

    Returns:
        The int.

    Raises:
        ArgumentError: a value of the wrong kind.
        ValueError: a value outside the range.
    """
    return integer(name, value, 0, MAX_SEED)


def flag(name: str, value: Any) -> bool:
    """``value`` as a bool: True or False (Python's or numpy's), nothing else.

    Args:
        name: the argument's name, which the error message gives.
        value: the value to check.

    Returns:
        The bool.

    Raises:
        ArgumentError: anything but a bool.
    """
    if not isinstance(value, (bool, np.bool_)):
        raise ArgumentError.about(name, f"expected True or False, got {_excerpt(value)}")
    return bool(value)


def choice(name: str, value: Any, choices: Iterable[Any]) -> Any:
    """``value`` if it is one of ``choices``.

    Args:
        name: the argument's name, which the error message gives.
        value: the value to check (a string).
        choices: the accepted strings.

    Returns:
        ``value``.

    Raises:
        ValueError: a value not among the choices.
    """
    return StrOptions(choices).check(name, value)


def vector(name: str, value: Any, size: int, low: float = -math.inf, high: Any = math.inf) -> np.ndarray:
    """A float vector (size,) from one number (for every entry) or ``size`` numbers.

    Args:
        name: the argument's name, which the error message gives.
        value: one number or ``size`` numbers.
        size: the vector's length.
        low: the lower bound of every entry.
        high: the upper bound, a number or a (size,) array.

    Returns:
        The (size,) float array.

    Raises:
        ArgumentError: a value of the wrong kind.
        ValueError: an entry not finite or outside [low, high].
    """
    items = [value] if _is_real(value) else value
    try:
        items = list(items)
    except TypeError:
        raise ArgumentError.about(name, f"expected a number or {size} numbers, got {_excerpt(value)}") from None
    if not all(_is_real(v) for v in items) or len(items) not in (1, size):
        raise ArgumentError.about(name, f"expected a number or {size} numbers, got {_excerpt(value)}")
    arr = np.array([_as_float(v) for v in items] * (size if len(items) == 1 else 1))
    high = np.broadcast_to(np.asarray(high, dtype=float), (size,))
    if not (np.all(np.isfinite(arr)) and np.all(arr >= low) and np.all(arr <= high)):
        top = f"{high[0]:g}" if np.all(high == high[0]) else f"({', '.join(f'{h:g}' for h in high)})"
        raise UsageError.about(name, f"expected finite numbers in [{low:g}, {top}], got {_excerpt(value)}")
    return arr


def interval(name: str, value: Any, low: float, high: float, *, low_open: bool = False) -> tuple[float, float]:
    """(min, max) of two real numbers with low <= min <= max <= high.

    Args:
        name: the argument's name, which the error message gives.
        value: the pair to check.
        low: the lower bound.
        high: the upper bound.
        low_open: require low < min.

    Returns:
        The pair (min, max) as floats.

    Raises:
        ArgumentError: not a pair of numbers.
        ValueError: numbers not finite, out of order or outside the bounds.
    """
    try:
        lo, hi = value
    except (TypeError, ValueError):
        raise ArgumentError.about(name, f"expected (min, max), got {_excerpt(value)}") from None
    span = _span(low, high, low_open)
    if not (_is_real(lo) and _is_real(hi)):
        raise ArgumentError.about(name, f"expected (min, max) of numbers {span}, got {_excerpt(value)}")
    lo, hi = _as_float(lo), _as_float(hi)
    if not (math.isfinite(lo) and math.isfinite(hi) and (lo > low if low_open else lo >= low) and lo <= hi <= high):
        raise UsageError.about(name, f"expected (min, max) with min <= max, both {span}, got {_excerpt(value)}")
    return lo, hi


def check_keywords(
    owner: str, kwargs: Mapping[str, Any], valid: Iterable[str], moved: Mapping[str, str] | None = None
) -> None:
    """Refuse keywords not in ``valid`` as Python refuses them in a call of ``owner``.

    Args:
        owner: the callable's name, which the message gives.
        kwargs: the keyword arguments given.
        valid: the accepted names.
        moved: a keyword that is no longer taken, mapped to where it went (said in the error).

    Raises:
        ArgumentError: an unknown keyword.
    """
    valid = tuple(valid)
    for key in kwargs:
        if key not in valid:
            hint = (moved or {}).get(key)
            where = hint if hint else f"valid keyword arguments: {', '.join(valid)}"
            raise ArgumentError(
                f"{owner}() got an unexpected keyword argument {key!r}; {where}",
                argument=key,
                problem=f"unexpected keyword argument; {where}",
            )


def check_action(action: Any, shape: tuple[int, ...]) -> np.ndarray:
    """The action as a float64 array of ``shape`` (see :func:`real_array`).

    Args:
        action: the action given to ``step``.
        shape: the action's shape.

    Returns:
        The float64 array.

    Raises:
        ArgumentError: not real numbers.
        ValueError: another shape, or a value not finite.
    """
    return real_array("action", action, shape)


def reset_options(options: Any, valid: Iterable[str] = ()) -> dict[str, Any]:
    """The ``options`` of ``reset()`` as a dict.

    Args:
        options: None (no options) or a mapping whose keys are among ``valid``.
        valid: the accepted option names.

    Returns:
        The options as a dict (empty for None).

    Raises:
        ArgumentError: not a mapping.
        ValueError: an unknown option; the message names ``options``.
    """
    valid = tuple(valid)
    if options is None:
        return {}
    if not isinstance(options, Mapping):
        problem = f"expected a dict (or None), got {_excerpt(options)}"
        raise ArgumentError(f"reset: options: {problem}", argument="options", problem=problem)
    unknown = [key for key in options if key not in valid]
    if unknown:
        problem = f"unknown option(s) {', '.join(_excerpt(k, 40) for k in unknown[:5])}; " + (
            f"valid: {', '.join(map(repr, valid))}" if valid else "this environment takes none"
        )
        raise UsageError(f"reset: options: {problem}", argument="options", problem=problem)
    return dict(options)


def plain(name: str, value: Any) -> Any:
    """``value`` with what numpy would misread made plain: a tensor (torch's or any with
    ``detach``) detached from its autograd graph and moved to the CPU (the simulation is not
    differentiable: no gradient flows through a step), a masked array without masked entries its
    data.  A masked array with masked entries is refused: the values under a mask are not data.

    Args:
        name: the argument's name, which the error message gives.
        value: the value to read.

    Returns:
        ``value`` made plain (anything else unchanged).

    Raises:
        ValueError: a masked array with masked entries.
    """
    if isinstance(value, np.ma.MaskedArray):
        masked = int(np.count_nonzero(np.ma.getmaskarray(value)))
        if masked:
            raise UsageError.about(
                name,
                f"a masked array with {masked} masked value(s); give plain numbers, e.g. "
                f"{name}.filled(0.0) to choose the value of the masked entries",
            )
        return np.ma.getdata(value)
    if callable(getattr(value, "detach", None)) and type(value).__module__.split(".")[0] == "torch":
        value = value.detach()
        return value.cpu() if callable(getattr(value, "cpu", None)) else value
    return value


def real_array(name: str, value: Any, shape: tuple[int, ...]) -> np.ndarray:
    """``value`` as a float64 array of ``shape``: real numbers (integers or floats of any width), finite.

    A torch tensor is read detached (see :func:`plain`).

    Args:
        name: the argument's name, which the error message gives.
        value: the value to check.
        shape: the required shape.

    Returns:
        The float64 array.

    Raises:
        ArgumentError: bools, complex numbers, strings, dates, objects, or a Python int beyond
            every integer type.
        ValueError: NaN, inf, another shape, or a masked array with masked entries.
    """
    if type(value) is np.ndarray:
        a = value  # a plain array: nothing to unwrap or convert
    else:
        value = plain(name, value)
        try:
            a = np.asarray(value)
        except (TypeError, ValueError, OverflowError, RuntimeError):  # RuntimeError: tensors numpy cannot read
            raise ArgumentError.about(name, f"expected real numbers of shape {shape}, got {_excerpt(value)}") from None
    if a.dtype.kind not in "iuf":
        hint = " (an integer too large for any integer type?)" if a.dtype.kind == "O" else ""
        raise ArgumentError.about(
            name,
            f"expected real numbers (integers or floats) of shape {shape}, "
            f"got dtype {a.dtype}{hint}: {_excerpt(value)}",
        )
    if a.shape != shape:
        raise UsageError.about(name, f"expected shape {shape}, got {a.shape}")
    a = a.astype(np.float64, copy=False)
    # One sum tells whether all is finite in the common case; only a non-finite sum looks closer.
    if not math.isfinite(a.sum()):
        bad = ~np.isfinite(a)
        if bad.any():
            where = np.argwhere(bad)[0]
            kind = "NaN" if np.isnan(a[tuple(where)]) else "inf"
            raise UsageError.about(
                name,
                f"contains {kind} at index {tuple(int(i) for i in where)} "
                f"({int(bad.sum())} non-finite value(s)); it must be finite",
            )
    return a
