"""Vestibular models: how a person perceives specific force and angular velocity.

Two linear models of the inner ear, each the same on the three axes of the head frame {H}, with
the parameters of Telban and Cardullo (2005), "Motion cueing algorithm development:
human-centered linear and nonlinear approaches", NASA CR-2005-213747, section 2 (after Young and
Meiry, 1968, "A revised dynamic otolith model", Aerospace Medicine 39(6), and Zacharias, 1978,
"Motion cue models for pilot-vehicle analysis", AMRL-TR-78-2):

- the **otolith** (specific force ``f`` in, perceived specific force out)::

      f_hat / f = K (tau_a s + 1) / ((tau_L s + 1)(tau_S s + 1)),
      K = 0.4, tau_a = 13.2 s, tau_L = 5.33 s, tau_S = 0.66 s;

  its gain peaks at 0.89 near 0.5 rad/s (above 0.8 from 0.23 to 1.06 rad/s) and is 0.4 at
  rest, so a sustained acceleration fades to 40 % of its size;
- the **semicircular canal** (angular velocity ``omega`` in, perceived angular velocity out)::

      omega_hat / omega = tau_L tau_a s^2 / ((tau_L s + 1)(tau_a s + 1)),
      tau_L = 5.73 s (cupula-endolymph), tau_a = 80 s (adaptation);

  a high pass: a constant rotation is felt to stop. The canal's short time constant (about
  5 ms) and its neural lead are left out, as Telban and Cardullo do for cueing.

A model's ``discretize(dt)`` gives a stateful filter that is exact for inputs that vary linearly
between samples (the first-order hold, or "triangle hold"): its outputs are the continuous model's
response to the samples joined by straight lines, at the sample times, to rounding. A filter steps
a batch of any leading shape; each element sees the same arithmetic, so a batch and its elements
one by one give the same numbers bit for bit.

:data:`THRESHOLDS` are the perception thresholds Telban and Cardullo (2005) use: below them a
motion is not felt.
"""

from __future__ import annotations

import math
import types
from dataclasses import dataclass

import numpy as np

from stewart_env.errors import UsageError

__all__ = [
    "THRESHOLDS",
    "THRESHOLDS_SOURCE",
    "Otolith",
    "SemicircularCanal",
    "SensorFilter",
    "false_cue_samples",
    "first_order_hold",
]

THRESHOLDS_SOURCE = (
    "Telban and Cardullo (2005), NASA CR-2005-213747: specific force 0.17, 0.17, 0.28 m/s² (x, y, z); "
    "angular velocity 3.0, 3.6, 2.6 deg/s (roll, pitch, yaw)"
)
"""Where :data:`THRESHOLDS` come from."""


def false_cue_samples(reference, signal, threshold) -> np.ndarray:
    """Where the platform's perceived motion is a false cue: above the perception threshold with
    the sign opposite to the vehicle's perceived motion (or where the vehicle's is zero).

    Args:
        reference: (..., k) the vehicle's perceived signal, per axis.
        signal: (..., k) the platform's perceived signal.
        threshold: (k,) the perception thresholds per axis (:data:`THRESHOLDS`).

    Returns:
        The (..., k) boolean mask of the false samples.
    """
    p = np.asarray(reference, dtype=float)
    q = np.asarray(signal, dtype=float)
    return (np.abs(q) > np.asarray(threshold, dtype=float)) & (p * q <= 0.0)


def _read_only(values) -> np.ndarray:
    array = np.array(values, dtype=np.float64)
    array.setflags(write=False)
    return array


THRESHOLDS = types.MappingProxyType(
    {
        # m/s², per axis of {H} (x forward, y left, z up)
        "specific_force": _read_only([0.17, 0.17, 0.28]),
        # rad/s, per axis of {H} (roll about x, pitch about y, yaw about z)
        "angular_velocity": _read_only(np.radians([3.0, 3.6, 2.6])),
    }
)
"""The perception thresholds per axis of {H}, under ``"specific_force"`` in m/s² and ``"angular_velocity"`` in rad/s."""


def _check_dt(dt) -> float:
    if isinstance(dt, bool) or not isinstance(dt, (int, float, np.floating)) or not math.isfinite(dt) or dt <= 0.0:
        raise UsageError.about("dt", f"must be a finite positive number of seconds, got {dt!r}")
    return float(dt)


def _check_time_constant(name: str, value) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0.0:
        raise UsageError.about(name, f"must be a finite positive number of seconds, got {value!r}")


def first_order_hold(numerator, denominator, dt: float):
    """A transfer function's state-space form and its first-order-hold discretisation.

    With the controllable form (A, B, C, D) of the transfer function, the exponential of the block
    matrix [[A dt, B dt, 0], [0, 0, 1], [0, 0, 0]] holds Phi = e^{A dt}, Gamma_1 = int_0^dt e^{A t}
    dt B and Gamma_2, the weight of the input's slope over the step (:class:`SensorFilter`).

    Args:
        numerator: the numerator, descending powers of s.
        denominator: the denominator, descending powers of s.
        dt: the sample period (s).

    Returns:
        The seven arrays A (n, n), B (n, 1), C (1, n) and D (1, 1) of ``scipy.signal.tf2ss``, then
        Phi (n, n), Gamma_1 (n,) and Gamma_2 (n,), in that order.
    """
    # here, not at the top: scipy.signal's and scipy.linalg's imports take about a second together
    from scipy.linalg import expm
    from scipy.signal import tf2ss

    a, b, c, d = tf2ss(numerator, denominator)
    n = a.shape[0]
    block = np.zeros((n + 2, n + 2))
    block[:n, :n] = a * dt
    block[:n, n : n + 1] = b * dt
    block[n, n + 1] = 1.0
    exponential = expm(block)
    return a, b, c, d, exponential[:n, :n], exponential[:n, n], exponential[:n, n + 1]


class SensorFilter:
    """A vestibular model discretised with a first-order hold: a stateful filter over (..., 3) inputs.

    With ``x`` the continuous model's state and ``u_k`` the input samples, one step is::

        x_k = Phi x_{k-1} + (Gamma_1 - Gamma_2) u_{k-1} + Gamma_2 u_k,   y_k = C x_k + D u_k,

    where ``Phi = e^{A dt}``, ``Gamma_1 = int_0^dt e^{A t} dt B`` and ``Gamma_2`` weighs the input's
    slope: the exact response to the input joined linearly between samples.

    The first step after :meth:`reset` starts from rest (state 0: a person who felt nothing
    before) or, given ``steady_input``, from the steady state under that constant input (a person
    adapted to it, such as gravity at rest).

    Args:
        numerator: the transfer function's numerator, descending powers of s.
        denominator: its denominator, descending powers of s (the models' poles are all stable).
        dt: the sample period (s).
    """

    def __init__(self, numerator, denominator, dt: float):
        self.dt = _check_dt(dt)
        a, b, c, d, phi, gamma_1, gamma_2 = first_order_hold(numerator, denominator, self.dt)
        n = a.shape[0]
        # Plain floats, combined element by element in a fixed order: the same arithmetic for
        # every element of a batch, whatever its shape.
        self._phi = [[float(v) for v in row] for row in phi]
        self._previous_gain = [float(v) for v in gamma_1 - gamma_2]
        self._current_gain = [float(v) for v in gamma_2]
        self._output = [float(v) for v in c[0]]
        self._feedthrough = float(d[0, 0])
        # x_ss = -A^-1 B u for a constant input u
        self._steady = [float(v) for v in -np.linalg.solve(a, b[:, 0])]
        self.order = n
        self._state: list[np.ndarray] | None = None
        self._previous: np.ndarray | None = None
        self._steady_input: np.ndarray | None = None

    def reset(self, steady_input=None) -> None:
        """Forget the past: the next step starts from rest, or from the steady state under ``steady_input``.

        Args:
            steady_input: None (start from rest) or an array of the inputs' shape (..., 3), the
                constant input the filter has been under before the next step.

        Raises:
            UsageError: ``steady_input`` is not finite or its last axis is not 3.
        """
        self._state = None
        self._previous = None
        self._steady_input = None
        if steady_input is not None:
            value = np.array(steady_input, dtype=np.float64)
            if value.ndim < 1 or value.shape[-1] != 3 or not np.isfinite(value).all():
                raise UsageError.about(
                    "steady_input", f"must be a finite array of shape (..., 3), got shape {value.shape}"
                )
            self._steady_input = value

    def start_rows(self, rows, steady_input) -> None:
        """Put elements ``rows`` of the batch's leading axis in the steady state under ``steady_input``.

        The filter has stepped (or been reset with ``steady_input``) a batch; the next step of
        those elements starts as if they had been under ``steady_input`` for long, as
        :meth:`reset` with ``steady_input`` starts a whole batch.

        Args:
            rows: (m,) int, indices into the batch's leading axis.
            steady_input: (m, ..., 3) the rows' constant inputs before the next step.

        Raises:
            UsageError: the filter holds no batch yet, or ``steady_input``'s shape is not the rows'.
        """
        if self._state is None and self._steady_input is None:
            raise UsageError.about(
                "rows", "the filter holds no batch yet: reset it with a steady_input or step it first"
            )
        if self._state is None:
            self._state = [gain * self._steady_input for gain in self._steady]
            self._previous = self._steady_input.copy()
        shape = self._state[0].shape
        value = np.asarray(steady_input, dtype=np.float64)
        rows = np.asarray(rows, dtype=np.int64)
        if value.shape != (len(rows), *shape[1:]):
            raise UsageError.about("steady_input", f"must have shape {(len(rows), *shape[1:])}, got {value.shape}")
        for state, gain in zip(self._state, self._steady):
            state[rows] = gain * value
        self._previous[rows] = value

    def step(self, u) -> np.ndarray:
        """Advance one sample: the perceived signal for the input sample ``u``.

        Args:
            u: the input sample, shape (..., 3): a batch of any leading shape, fixed from the
                first step after a reset.

        Returns:
            The output sample, shape (..., 3), float64.

        Raises:
            UsageError: ``u``'s shape differs from the first step's, or from ``steady_input``'s.
        """
        u = np.asarray(u, dtype=np.float64)
        if u.ndim < 1 or u.shape[-1] != 3:
            raise UsageError.about("u", f"must have shape (..., 3), got {u.shape}")
        if self._state is None:
            if self._steady_input is not None:
                if self._steady_input.shape != u.shape:
                    raise UsageError.about(
                        "u",
                        f"has shape {u.shape} but the filter was reset with steady_input of shape {self._steady_input.shape}",
                    )
                base = self._steady_input
                self._state = [gain * base for gain in self._steady]
                self._previous = base.copy()
            else:
                self._state = [np.zeros_like(u) for _ in range(self.order)]
                self._previous = None
        elif u.shape != self._state[0].shape:
            raise UsageError.about(
                "u", f"has shape {u.shape}, but this filter has stepped inputs of shape {self._state[0].shape}"
            )
        if self._previous is not None:
            x = self._state
            state = []
            for i in range(self.order):
                row = self._phi[i]
                value = row[0] * x[0]
                for j in range(1, self.order):
                    value = value + row[j] * x[j]
                value = value + self._previous_gain[i] * self._previous + self._current_gain[i] * u
                state.append(value)
            self._state = state
        # else: the first sample from rest, state 0
        output = self._feedthrough * u
        for j in range(self.order):
            output = output + self._output[j] * self._state[j]
        self._previous = u.copy()
        return output


@dataclass(frozen=True)
class _LinearModel:
    """What both models share: a transfer function, its discretisation and whole-signal perception."""

    def transfer_function(self) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover - overridden
        raise NotImplementedError

    def discretize(self, dt: float) -> SensorFilter:
        """The model as a filter of period ``dt``, exact for inputs linear between samples.

        Args:
            dt: the sample period (s), > 0.

        Returns:
            A :class:`SensorFilter` at rest.

        Raises:
            UsageError: ``dt`` is not a finite positive number.
        """
        numerator, denominator = self.transfer_function()
        return SensorFilter(numerator, denominator, dt)

    def perceive(self, signal, dt: float, start: str = "steady") -> np.ndarray:
        """The perceived signal for a whole signal sampled every ``dt`` seconds.

        Args:
            signal: (T, 3) the input (specific force in m/s² or angular velocity in rad/s, in {H}).
            dt: its sample period (s), > 0.
            start: ``"steady"`` (the person has been under the first sample for long: the
                otolith at rest reads gravity without a transient) or ``"rest"`` (state 0).

        Returns:
            (T, 3) float64, the perceived signal at the same samples.

        Raises:
            UsageError: ``signal`` is not a finite (T, 3) array, ``dt`` is not positive or
                ``start`` is not one of the two.
        """
        values = np.asarray(signal, dtype=np.float64)
        if values.ndim != 2 or values.shape[1] != 3 or len(values) == 0:
            raise UsageError.about("signal", f"must have shape (T, 3) with T >= 1, got {values.shape}")
        if not np.isfinite(values).all():
            row = int(np.argwhere(~np.isfinite(values))[0][0])
            raise UsageError.about("signal", f"has a non-finite value at sample {row}")
        if start not in ("steady", "rest"):
            raise UsageError.about("start", f"must be 'steady' or 'rest', got {start!r}")
        sensor = self.discretize(dt)
        sensor.reset(values[0] if start == "steady" else None)
        out = np.empty_like(values)
        for k in range(len(values)):
            out[k] = sensor.step(values[k])
        return out


@dataclass(frozen=True)
class Otolith(_LinearModel):
    """The otolith organs: specific force in, perceived specific force out (Telban and Cardullo, 2005).

    ``K (tau_a s + 1) / ((tau_L s + 1)(tau_S s + 1))`` on each axis of {H}, after Young and
    Meiry (1968), scaled so that the gain is near 1 (0.89 at its peak, near 0.5 rad/s) in the
    band where the otoliths sense best.

    Attributes:
        gain: K, the gain at rest (0.4).
        lead_time_constant: tau_a (s), 13.2.
        long_time_constant: tau_L (s), 5.33.
        short_time_constant: tau_S (s), 0.66.
    """

    gain: float = 0.4
    lead_time_constant: float = 13.2
    long_time_constant: float = 5.33
    short_time_constant: float = 0.66

    def __post_init__(self) -> None:
        """Check the parameters: positive and finite."""
        for name in ("gain", "lead_time_constant", "long_time_constant", "short_time_constant"):
            _check_time_constant(name, getattr(self, name))

    def transfer_function(self) -> tuple[np.ndarray, np.ndarray]:
        """The transfer function in s.

        Returns:
            The numerator and the denominator, coefficients in descending powers of s.
        """
        numerator = self.gain * np.array([self.lead_time_constant, 1.0])
        denominator = np.polymul([self.long_time_constant, 1.0], [self.short_time_constant, 1.0])
        return numerator, denominator


@dataclass(frozen=True)
class SemicircularCanal(_LinearModel):
    """The semicircular canals: angular velocity in, perceived angular velocity out (Telban and Cardullo, 2005).

    ``tau_L tau_a s^2 / ((tau_L s + 1)(tau_a s + 1))`` on each axis of {H}: the cupula-endolymph
    torsion pendulum's long time constant and the adaptation, unit gain in the mid band.

    Attributes:
        long_time_constant: tau_L (s), 5.73.
        adaptation_time_constant: tau_a (s), 80.
    """

    long_time_constant: float = 5.73
    adaptation_time_constant: float = 80.0

    def __post_init__(self) -> None:
        """Check the parameters: positive and finite."""
        for name in ("long_time_constant", "adaptation_time_constant"):
            _check_time_constant(name, getattr(self, name))

    def transfer_function(self) -> tuple[np.ndarray, np.ndarray]:
        """The transfer function in s.

        Returns:
            The numerator and the denominator, coefficients in descending powers of s.
        """
        product = self.long_time_constant * self.adaptation_time_constant
        numerator = np.array([product, 0.0, 0.0])
        denominator = np.polymul([self.long_time_constant, 1.0], [self.adaptation_time_constant, 1.0])
        return numerator, denominator
