"""Classical washout: the motion cueing algorithm of flight and driving simulators, in the
structure of Reid and Nahon (1985), as a policy of the cueing task in ``action_mode="pose"``.

The vehicle's specific force f (m/s²) and angular velocity omega (rad/s) at the head, in the head
frame {H} (x forward, y left, z up), go through three channels (per axis, ``WashoutParams``):

* **translational**: the specific force less its value at rest, f - (0, 0, g), scaled by
  ``force_scale`` and limited to ``force_limit``, is high-passed by a 2nd-order filter
  s² / (s² + 2 zeta w s + w²) and a 1st-order s / (s + w_b) (3rd order in all; w_b = 0 leaves
  the 2nd-order filter) and integrated twice to the platform's displacement.  The high-pass and
  the double integration are one transfer function, s / ((s² + 2 zeta w s + w²)(s + w_b)), so
  that a sustained specific force leaves no drift: with w_b > 0 the displacement of a step
  returns to zero.
* **tilt coordination**: the scaled, limited specific force's x and y through a 2nd-order
  low-pass w² / (s² + 2 zeta w s + w²) give the sustained part that gravity renders by tilting
  the cabin, pitch = -asin(f_x / g), roll = asin(f_y / (g cos pitch)) (a tilted cabin at rest
  feels f = R^T (0, 0, g)), each angle's rate limited to ``tilt_rate_limit`` (3 deg/s by default,
  below the canals' threshold, so the tilt itself is not perceived as a rotation).
* **rotational**: the angular velocity, scaled and limited, is high-passed by
  s² / (s² + 2 zeta w s + w²) and integrated once to the roll, pitch and yaw angles, one transfer
  function s / (s² + 2 zeta w s + w²) (angles of small motions: the Euler rates are taken equal
  to the angular velocity).  The tilt adds to roll and pitch.

Each transfer function is discretised at the control rate with the bilinear (Tustin) transform
(:func:`discretize`), which keeps stability and matches the continuous frequency response within
0.3 % up to 10 rad/s at 10 ms (the frequency warping tan(w T / 2) 2 / T - w).

The displacement and angles are the head's pose relative to home in {H}; the commanded pose
rotates the cabin about the head point ``head`` (in {P}, m), and its action is the environment's
pose-mode normalisation of it (``Actuation.pose_command``), clipped to [-1, 1].

Reference: R. Reid, M. A. Nahon, "Flight simulation motion-base drive algorithms: part 1,
developing and testing the equations", UTIAS Report 296, 1985.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

from stewart_env.errors import UsageError
from stewart_env.files import DocumentError, FileError, load_yaml, read_regular
from stewart_env.params import MAX_CONFIG_BYTES, config_dir
from stewart_env.rotations import rpy_to_matrix
from stewart_env.tasks.cueing.motion import STANDARD_GRAVITY

__all__ = [
    "DiscreteFilter",
    "Washout",
    "WashoutParams",
    "WashoutPolicy",
    "bilinear",
    "discretize",
    "head_pose",
    "load_washout_params",
    "washout_transfer_functions",
]


@dataclass(frozen=True)
class WashoutParams:
    """The classical washout's parameters, per axis of {H} (x, y, z or roll, pitch, yaw).

    The defaults are the starting point of the tuning (``tune_washout``), values of the order that
    Reid and Nahon (1985) and the driving-simulator literature use for a platform of a few tens of
    centimetres: the tuned values are shipped in configs/agents/washout.yaml.

    Attributes:
        force_scale: gains on the specific force's deviation from rest (x, y, z), dimensionless.
        force_limit: limits of the scaled deviation (x, y, z), m/s².
        translational_frequency: w of the 2nd-order high-pass (x, y, z), rad/s.
        translational_damping: zeta of the 2nd-order high-pass (x, y, z).
        translational_break: w_b of the 1st-order high-pass (x, y, z), rad/s; 0 leaves the 2nd order.
        tilt_frequency: w of the tilt's low-pass (x -> pitch, y -> roll), rad/s.
        tilt_damping: zeta of the tilt's low-pass (x, y).
        tilt_rate_limit: the largest tilt rate, rad/s (3 deg/s).
        tilt_limit: the largest tilt angle, rad.
        angular_scale: gains on the angular velocity (roll, pitch, yaw), dimensionless.
        angular_limit: limits of the scaled angular velocity, rad/s.
        rotational_frequency: w of the rotational 2nd-order high-pass, rad/s.
        rotational_damping: zeta of the rotational high-pass.
    """

    force_scale: tuple[float, float, float] = (0.5, 0.5, 0.5)
    force_limit: tuple[float, float, float] = (5.0, 5.0, 5.0)
    translational_frequency: tuple[float, float, float] = (2.5, 2.5, 4.0)
    translational_damping: tuple[float, float, float] = (1.0, 1.0, 1.0)
    translational_break: tuple[float, float, float] = (0.5, 0.5, 1.0)
    tilt_frequency: tuple[float, float] = (2.0, 2.0)
    tilt_damping: tuple[float, float] = (1.0, 1.0)
    tilt_rate_limit: float = math.radians(3.0)
    tilt_limit: float = math.radians(20.0)
    angular_scale: tuple[float, float, float] = (0.5, 0.5, 0.5)
    angular_limit: tuple[float, float, float] = (1.0, 1.0, 1.0)
    rotational_frequency: tuple[float, float, float] = (1.0, 1.0, 1.0)
    rotational_damping: tuple[float, float, float] = (1.0, 1.0, 1.0)

    def __post_init__(self) -> None:
        """Check every field: finite, the right length, positive (the scales, the breaks >= 0)."""
        for item in fields(self):
            value = getattr(self, item.name)
            scalar = item.name in ("tilt_rate_limit", "tilt_limit")
            size = 2 if item.name.startswith("tilt_") else 3
            array = np.asarray(value, dtype=float) if _numeric(value) else None
            if array is None or (array.shape != () if scalar else array.shape != (size,)):
                shape = "a number" if scalar else f"{size} numbers"
                raise UsageError.about(item.name, f"must be {shape}, got {value!r}")
            nonnegative = item.name in ("translational_break", "force_scale", "angular_scale")
            if not np.all(np.isfinite(array)) or np.any(array < 0) or (not nonnegative and np.any(array == 0)):
                bound = ">= 0" if nonnegative else "> 0"
                raise UsageError.about(item.name, f"must be finite and {bound}, got {value!r}")
            if item.name == "tilt_limit" and array >= math.pi / 2:
                raise UsageError.about(item.name, f"must be below pi/2 rad, got {value!r}")
            object.__setattr__(self, item.name, float(array) if scalar else tuple(float(v) for v in array))

    @classmethod
    def from_mapping(cls, values, source: str = "params") -> WashoutParams:
        """The parameters of a mapping of field names (a config file's), unknown names refused.

        Args:
            values: field name -> value; missing fields keep their defaults.
            source: what the mapping is, for errors (a file name).

        Returns:
            The checked parameters.

        Raises:
            UsageError: an unknown field or a bad value, named with ``source``.
        """
        if not isinstance(values, dict):
            raise UsageError.about(source, f"must be a mapping of washout parameters, got {type(values).__name__}")
        known = {item.name for item in fields(cls)}
        unknown = sorted(set(values) - known)
        if unknown:
            raise UsageError.about(source, f"unknown washout parameters {unknown}; known: {sorted(known)}")
        try:
            return cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in values.items()})
        except UsageError as error:
            raise UsageError.about(f"{source}: {error.argument}", error.problem or str(error)) from None

    def as_dict(self) -> dict:
        """Field name -> value (lists for the per-axis fields), as a config file holds them."""
        return {item.name: _plain(getattr(self, item.name)) for item in fields(self)}


def _numeric(value) -> bool:
    try:
        np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        return False
    return not isinstance(value, (str, bytes, bool))


def _plain(value):
    return list(value) if isinstance(value, tuple) else value


def washout_transfer_functions(params: WashoutParams) -> dict[str, list[tuple[np.ndarray, np.ndarray]]]:
    """The continuous transfer functions (num, den), polynomials in s, of each channel, per axis.

    Args:
        params: the washout's parameters.

    Returns:
        ``"translational_highpass"`` (x, y, z: the 3rd-order high-pass on the scaled specific
        force), ``"translational_position"`` (x, y, z: that high-pass integrated twice, m per
        m/s²), ``"tilt_lowpass"`` (x, y), ``"rotational_highpass"`` and ``"rotational_angle"``
        (roll, pitch, yaw: the high-pass on the angular velocity, and it integrated once).
    """
    out: dict[str, list[tuple[np.ndarray, np.ndarray]]] = {k: [] for k in _CHANNELS}
    for w, zeta, wb in zip(params.translational_frequency, params.translational_damping, params.translational_break):
        second = np.array([1.0, 2.0 * zeta * w, w * w])
        den = np.polymul(second, [1.0, wb])
        out["translational_highpass"].append((np.array([1.0, 0.0, 0.0, 0.0]), den))
        out["translational_position"].append((np.array([1.0, 0.0]), den))
    for w, zeta in zip(params.tilt_frequency, params.tilt_damping):
        out["tilt_lowpass"].append((np.array([w * w]), np.array([1.0, 2.0 * zeta * w, w * w])))
    for w, zeta in zip(params.rotational_frequency, params.rotational_damping):
        den = np.array([1.0, 2.0 * zeta * w, w * w])
        out["rotational_highpass"].append((np.array([1.0, 0.0, 0.0]), den))
        out["rotational_angle"].append((np.array([1.0, 0.0]), den))
    return out


_CHANNELS = (
    "translational_highpass",
    "translational_position",
    "tilt_lowpass",
    "rotational_highpass",
    "rotational_angle",
)


class DiscreteFilter:
    """A bank of discrete linear filters, one per channel, run on batches of signals.

    Each channel's filter is b(z) / a(z) (coefficients of z^-k, a[0] = 1), realised in transposed
    direct form II; the state has the shape of the input plus the order, made at the first step.

    Args:
        coefficients: per channel, (b, a) of the same order.
    """

    def __init__(self, coefficients: list[tuple[np.ndarray, np.ndarray]]):
        order = max(max(len(b), len(a)) for b, a in coefficients) - 1
        self.b = np.zeros((len(coefficients), order + 1))
        self.a = np.zeros((len(coefficients), order + 1))
        for k, (b, a) in enumerate(coefficients):
            self.b[k, order + 1 - len(b) :] = np.asarray(b, dtype=float) / a[0]
            self.a[k, order + 1 - len(a) :] = np.asarray(a, dtype=float) / a[0]
        self.order = order
        self.state: np.ndarray | None = None

    def reset(self, rows=None) -> None:
        """Zero the state (of ``rows`` of the leading axis, or all of it).

        Args:
            rows: a boolean mask or indices of the leading axis; None: everything.
        """
        if self.state is None:
            return
        if rows is None:
            self.state = None
        else:
            self.state[rows] = 0.0

    def step(self, u) -> np.ndarray:
        """Advance one sample.

        Args:
            u: (..., channels) the input at this sample.

        Returns:
            (..., channels) the output at this sample.
        """
        u = np.asarray(u, dtype=float)
        if self.state is None or self.state.shape[:-1] != u.shape:
            self.state = np.zeros(u.shape + (self.order,))
        z = self.state
        y = self.b[:, 0] * u + (z[..., 0] if self.order else 0.0)
        for i in range(self.order):
            following = z[..., i + 1] if i + 1 < self.order else 0.0
            z[..., i] = self.b[:, i + 1] * u + following - self.a[:, i + 1] * y
        return y


def bilinear(num, den, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """The bilinear (Tustin) transform of a transfer function: s = (2 / dt) (z - 1) / (z + 1).

    Written out with polynomial products (multiplying through by (z + 1)^n, n the denominator's
    degree), which needs no matrix solve.

    Args:
        num: the numerator in descending powers of s, of degree at most the denominator's.
        den: the denominator in descending powers of s.
        dt: the sampling period, s.

    Returns:
        (b, a), in descending powers of z (equally of z^-k), normalised so that a[0] = 1.
    """
    num = np.trim_zeros(np.atleast_1d(np.asarray(num, dtype=float)), "f")
    den = np.trim_zeros(np.atleast_1d(np.asarray(den, dtype=float)), "f")
    n = len(den) - 1
    c = 2.0 / dt

    def mapped(poly: np.ndarray) -> np.ndarray:
        out = np.zeros(n + 1)
        degree = len(poly) - 1
        for k, coefficient in enumerate(poly):  # coefficient of s^(degree - k)
            power = degree - k
            term = coefficient * c**power * np.polymul(_power([1.0, -1.0], power), _power([1.0, 1.0], n - power))
            out[n + 1 - len(term) :] += term
        return out

    b, a = mapped(num), mapped(den)
    return b / a[0], a / a[0]


def _power(poly, k: int) -> np.ndarray:
    out = np.array([1.0])
    for _ in range(k):
        out = np.polymul(out, poly)
    return out


def discretize(transfer_functions: list[tuple[np.ndarray, np.ndarray]], dt: float) -> DiscreteFilter:
    """The bilinear (Tustin) discretisation of continuous filters, one per channel, as a bank.

    Args:
        transfer_functions: per channel, (num, den) polynomials in s.
        dt: the sampling period, s.

    Returns:
        The discrete filter bank.
    """
    coefficients = []
    for num, den in transfer_functions:
        coefficients.append(bilinear(num, den, dt))
    return DiscreteFilter(coefficients)


class Washout:
    """The classical washout's state machine, for a batch of vehicle motions side by side.

    Args:
        params: the parameters.
        dt: the control period, s.
    """

    def __init__(self, params: WashoutParams, dt: float):
        if not isinstance(params, WashoutParams):
            raise UsageError.about("params", f"expected WashoutParams, got {type(params).__name__}")
        self.params = params
        self.dt = float(dt)
        tfs = washout_transfer_functions(params)
        self.position_filter = discretize(tfs["translational_position"], self.dt)
        self.tilt_filter = discretize(tfs["tilt_lowpass"], self.dt)
        self.angle_filter = discretize(tfs["rotational_angle"], self.dt)
        self._scale_f = np.array(params.force_scale)
        self._limit_f = np.array(params.force_limit)
        self._scale_w = np.array(params.angular_scale)
        self._limit_w = np.array(params.angular_limit)
        self.tilt: np.ndarray | None = None

    def reset(self, rows=None) -> None:
        """Start over (the rows ``rows`` of the batch, or all).

        Args:
            rows: a boolean mask or indices of the batch; None: everything.
        """
        for f in (self.position_filter, self.tilt_filter, self.angle_filter):
            f.reset(rows)
        if self.tilt is not None:
            if rows is None:
                self.tilt = None
            else:
                self.tilt[rows] = 0.0

    def tilt_target(self, lowpassed) -> np.ndarray:
        """The (roll, pitch) that renders a sustained specific force (x, y) with gravity, limited.

        Args:
            lowpassed: (..., 2) the low-passed specific force's x and y, m/s².

        Returns:
            (..., 2) roll and pitch, rad.
        """
        bound = math.sin(self.params.tilt_limit)
        pitch = -np.arcsin(np.clip(lowpassed[..., 0] / STANDARD_GRAVITY, -bound, bound))
        roll = np.arcsin(np.clip(lowpassed[..., 1] / (STANDARD_GRAVITY * np.cos(pitch)), -bound, bound))
        return np.stack([roll, pitch], axis=-1)

    def step(self, specific_force, angular_velocity) -> tuple[np.ndarray, np.ndarray]:
        """One control step: the head's displacement and angles for the vehicle's motion now.

        Args:
            specific_force: (..., 3) the vehicle's specific force in {H}, m/s².
            angular_velocity: (..., 3) its angular velocity in {H}, rad/s.

        Returns:
            (displacement (..., 3) m, rpy (..., 3) rad), relative to home, in {H}.
        """
        f = np.asarray(specific_force, dtype=float).copy()
        f[..., 2] -= STANDARD_GRAVITY
        f = np.clip(self._scale_f * f, -self._limit_f, self._limit_f)
        w = np.clip(self._scale_w * np.asarray(angular_velocity, dtype=float), -self._limit_w, self._limit_w)
        displacement = self.position_filter.step(f)
        angles = self.angle_filter.step(w)
        target = self.tilt_target(self.tilt_filter.step(f[..., :2]))
        if self.tilt is None or self.tilt.shape != target.shape:
            self.tilt = np.zeros_like(target)
        most = self.params.tilt_rate_limit * self.dt
        self.tilt = self.tilt + np.clip(target - self.tilt, -most, most)
        angles[..., :2] += self.tilt
        return displacement, angles

    def run(self, specific_force, angular_velocity) -> tuple[np.ndarray, np.ndarray]:
        """A whole motion (or a batch of them) from rest: the steps' outputs stacked.

        Args:
            specific_force: (T, ..., 3) m/s².
            angular_velocity: (T, ..., 3) rad/s.

        Returns:
            (displacement (T, ..., 3) m, rpy (T, ..., 3) rad).
        """
        self.reset()
        out = [self.step(f, w) for f, w in zip(np.asarray(specific_force), np.asarray(angular_velocity))]
        return np.stack([d for d, _ in out]), np.stack([a for _, a in out])


class WashoutPolicy:
    """Classical washout as a policy of the cueing task, with Stable-Baselines3's ``predict``.

    It reads the observation's parts ``vehicle_specific_force`` and ``vehicle_angular_velocity``
    (in physical units, through the environment's ``decode_observation``), steps a
    ``Washout`` per row and commands the pose it gives: the head at home plus the
    displacement, the cabin rotated by the angles about the head point, as the environment's pose
    action (needs ``action_mode="pose"``).  It keeps the filters' state per row: the state starts
    over when the batch's size changes, at SB3's ``episode_start`` rows and at :meth:`reset`.

    Args:
        env: the cueing environment (single, vector or SB3 VecEnv), ``action_mode="pose"``.
        params: the washout's parameters, or a path to a YAML file of them (default the
            :class:`WashoutParams` defaults).
        head: the head point in {P}, m: the centre of the cabin's rotations (default P's origin,
            or the task's ``head`` when the task has one).

    Raises:
        UsageError: an environment without the vehicle parts or not in pose mode, bad params.
    """

    PARTS = ("vehicle_specific_force", "vehicle_angular_velocity")

    def __init__(self, env, params: WashoutParams | str | None = None, head=None):
        env = base = cueing_environment(env)
        missing = [k for k in self.PARTS if k not in base.observation_layout]
        if missing:
            raise UsageError.about("env", f"its observations lack {missing}; washout needs task='cueing'")
        actuation = getattr(getattr(base, "_core", None), "actuation", None)
        if actuation is None or getattr(actuation, "pose_half", None) is None or not _pose_mode(base):
            raise UsageError.about("env", "washout commands poses: make the environment with action_mode='pose'")
        if params is None:
            params = WashoutParams()
        elif not isinstance(params, WashoutParams):
            params = load_washout_params(params)
        self.env = env
        self.params = params
        self.washout = Washout(params, base.dt)
        self._actuation = actuation
        if head is None:
            head = getattr(getattr(base, "task", None), "head", (0.0, 0.0, 0.0))
        self.head = np.asarray(head, dtype=float)
        if self.head.shape != (3,) or not np.all(np.isfinite(self.head)):
            raise UsageError.about("head", f"must be three finite numbers (m, in {{P}}), got {head!r}")

    def reset(self) -> None:
        """Start every row's filters over (a new batch of episodes)."""
        self.washout.reset()

    def pose(self, displacement, rpy) -> tuple[np.ndarray, np.ndarray]:
        """The platform pose in {B} of the head's displacement and the cabin's angles (``head_pose``).

        Args:
            displacement: (N, 3) the head's displacement in {H}, m.
            rpy: (N, 3) the cabin's roll, pitch, yaw relative to home, rad.

        Returns:
            (position (N, 3) of P in {B}, m; rotation (N, 3, 3)).
        """
        return head_pose(self.env.unwrapped.platform, self.head, displacement, rpy)

    def predict(self, observation, state=None, episode_start=None, deterministic: bool = True):
        """SB3's interface: (action (6,) or (N, 6), None) for one observation or a batch.

        Args:
            observation: one observation (obs_dim,) or a batch (N, obs_dim).
            state: SB3's recurrent state; unused (the filters' state is kept here).
            episode_start: SB3's episode starts (N,) bool: those rows' filters start over.
            deterministic: SB3's flag; unused (the policy is deterministic).

        Returns:
            (action, None).
        """
        obs = np.asarray(observation)
        part = self.env.unwrapped.decode_observation(np.atleast_2d(obs).astype(float))
        starts = starting_rows(episode_start)
        if starts is not None:
            self.washout.reset(starts)
        displacement, rpy = self.washout.step(part["vehicle_specific_force"], part["vehicle_angular_velocity"])
        position, rotation = self.pose(displacement, rpy)
        return pose_actions(self._actuation, position, rotation, obs.ndim == 1), None


def starting_rows(episode_start) -> np.ndarray | None:
    """SB3's ``episode_start`` as the (N,) mask of the rows that start over, or None when none does.

    Args:
        episode_start: None or (N,) booleans.
    """
    if episode_start is None:
        return None
    starts = np.asarray(episode_start, dtype=bool).reshape(-1)
    return starts if starts.any() else None


def pose_actions(actuation, position, rotation, single: bool) -> np.ndarray:
    """The pose-mode actions of commanded poses: the environment's normalisation, clipped to [-1, 1].

    Args:
        actuation: the environment's actuation (its ``pose_command``).
        position: (N, 3) P's commanded positions, m.
        rotation: (N, 3, 3) the commanded rotations.
        single: return the first row's (6,) action, for one observation.

    Returns:
        The float32 actions, (N, 6) or (6,).
    """
    action = np.stack([actuation.pose_command(p, r) for p, r in zip(position, rotation)])
    action = np.clip(action, -1.0, 1.0).astype(np.float32)
    return action[0] if single else action


def head_pose(platform, head, displacement, rpy) -> tuple[np.ndarray, np.ndarray]:
    """The platform pose that puts the head at home plus ``displacement``, the cabin turned by ``rpy``.

    The cabin turns about the head point, which moves by the displacement only:
    R = R_home R(rpy) and P = P_home + R_home (head + displacement) - R head.

    Args:
        platform: the platform's parameters (its home pose).
        head: (3,) the head point in {P}, m.
        displacement: (..., 3) the head's displacement in {H} (the platform's axes at home), m.
        rpy: (..., 3) the cabin's roll, pitch, yaw relative to home, rad.

    Returns:
        (position (..., 3) of P's origin in {B}, m; rotation (..., 3, 3) of {P} in {B}).
    """
    home_rotation = rpy_to_matrix(np.asarray(platform.home_rpy, dtype=float))
    head = np.asarray(head, dtype=float)
    rotation = home_rotation @ rpy_to_matrix(np.asarray(rpy, dtype=float))
    position = (
        np.asarray(platform.home_position, dtype=float)
        + (head + np.asarray(displacement, dtype=float)) @ home_rotation.T
        - rotation @ head
    )
    return position, rotation


def cueing_environment(env):
    """The stewart-env environment under ``env``: a Gymnasium or native vector environment's
    ``unwrapped``, or the one a Stable-Baselines3 ``VecEnv`` wraps (``venv``, followed down).

    Args:
        env: an environment of this package, or a wrapper of one.

    Raises:
        UsageError: no such environment under ``env`` (the message names ``env``).
    """
    seen = 0
    while env is not None and seen < 16:
        base = getattr(env, "unwrapped", None)
        if hasattr(base, "observation_layout") and hasattr(base, "decode_observation"):
            return base
        env, seen = getattr(env, "venv", None), seen + 1
    raise UsageError.about(
        "env", "expected a stewart-env environment (Gymnasium, vector or SB3 VecEnv) on task='cueing'"
    )


def _pose_mode(base) -> bool:
    config = getattr(getattr(base, "_core", None), "config", None)
    return getattr(getattr(config, "actuator", None), "action_mode", None) == "pose"


def load_washout_params(path) -> WashoutParams:
    """The washout parameters of a YAML file (configs/agents/washout.yaml's format: a mapping
    ``params:`` of :class:`WashoutParams` fields).

    Args:
        path: the file, or a shipped config's name ("washout" for configs/agents/washout.yaml).

    Returns:
        The checked parameters.

    Raises:
        UsageError: a missing or malformed file, an unknown or bad parameter, named with the file.
    """
    file = Path(path)
    if not file.suffix:
        file = config_dir("agents") / f"{path}.yaml"
    try:
        data = load_yaml(read_regular(file, MAX_CONFIG_BYTES, "washout config"))
    except FileError as error:
        raise UsageError.about("params", str(error)) from None
    except DocumentError as error:
        raise UsageError.about("params", f"{file}: {error.problem}") from None
    if not isinstance(data, dict) or "params" not in data:
        raise UsageError.about("params", f"{file} has no 'params' mapping")
    return WashoutParams.from_mapping(data["params"], source=f"{file}: params")
