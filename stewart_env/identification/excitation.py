"""Excitation trajectories: finite Fourier series in task space, optimised for the condition
number of the stacked base regressor within the platform's limits.

Each task coordinate q_j (x, y, z of P's origin in {B}, m; roll, pitch, yaw, rad) follows

    q_j(t) = q0_j + sum_{k=1..H} a_jk / (k wf) sin(k wf t) - b_jk / (k wf) cos(k wf t),

a series of period 2 pi / wf (Swevers et al. 1997).  It is evaluated in one place, the compiled
``stewart_env/_core/cpp/identification/excitation_law.hpp``: its law tracks the series by computed torque on
the plant, and :meth:`Excitation.sample` calls the same function.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.optimize

from stewart_env import _core
from stewart_env.dynamics.model import Dynamics
from stewart_env.dynamics.rk4 import ControlLaw
from stewart_env.identification import regressor as reg
from stewart_env.identification.base import BaseParameters, IdentificationError
from stewart_env.kinematics import inverse_kinematics, jacobian
from stewart_env.params import PlatformParams
from stewart_env.rotations import rpy_rate_matrix, rpy_to_matrix

#: The compiled computed-torque law along a Fourier excitation (its parameter row: :meth:`Excitation.law_row`).
FOURIER_COMPUTED_TORQUE = ControlLaw._compiled(_core.FOURIER_COMPUTED_TORQUE, None, "fourier_computed_torque")
#: Share of each limit the excitation may use: a margin for the tracking error of the plant.
LIMIT_SHARE = 0.85


@dataclass(frozen=True)
class Excitation:
    """A finite Fourier series in task space: q0 (6,), coefficients a, b (6, H), base angular
    frequency wf (rad/s)."""

    q0: np.ndarray
    a: np.ndarray
    b: np.ndarray
    wf: float

    @property
    def harmonics(self) -> int:
        """The number H of harmonics."""
        return int(self.a.shape[1])

    @property
    def period(self) -> float:
        """The series' period 2 pi / wf, s."""
        return 2 * math.pi / self.wf

    def sample(self, times) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """q, qdot, qddot (T, 6) at the given times (s), by the compiled series of the law.

        Args:
            times: the times (T,), s.
        """
        t = np.ascontiguousarray(times, dtype=float).reshape(-1)
        out = np.empty((t.size, 3, 6))
        _core.fourier_series(
            *(np.ascontiguousarray(x, dtype=float) for x in (self.q0, self.a, self.b)), float(self.wf), t, out
        )
        return tuple(np.ascontiguousarray(out[:, i]) for i in range(3))

    def law_row(self, controller: Dynamics, natural_frequency: float = 20.0, damping: float = 1.0) -> np.ndarray:
        """The parameter row of :data:`FOURIER_COMPUTED_TORQUE`: gains Kp = wn^2, Kd = 2 zeta wn on
        every coordinate, the controller's model and its first platform.

        Args:
            controller: the computed-torque controller's dynamics model.
            natural_frequency: the closed loop's natural frequency wn, rad/s.
            damping: its damping ratio zeta.
        """
        kp = np.full(6, natural_frequency**2)
        kd = np.full(6, 2 * damping * natural_frequency)
        return np.concatenate(
            [
                kp,
                kd,
                [controller.flags, self.wf, self.harmonics],
                self.q0,
                self.a.ravel(),
                self.b.ravel(),
                controller.packed[0],
            ]
        )

    def to_dict(self) -> dict:
        """The series as JSON-fit lists: q0, a, b and wf."""
        return {"q0": self.q0.tolist(), "a": self.a.tolist(), "b": self.b.tolist(), "wf": self.wf}


def task_states(q, qd, qdd):
    """(t, R, v, w, a, alpha) of task-space samples: omega = E(rpy) rpy_dot and
    alpha = E rpy_ddot + Edot rpy_dot (E of :func:`stewart_env.rotations.rpy_rate_matrix`).

    Args:
        q: the poses (T, 6): position of P's origin in {B}, m, and roll-pitch-yaw angles, rad.
        qd: their rates (T, 6), m/s and rad/s.
        qdd: their second derivatives (T, 6), m/s^2 and rad/s^2.
    """
    rpy, rate, acc = q[:, 3:], qd[:, 3:], qdd[:, 3:]
    E = rpy_rate_matrix(rpy)
    cp, sp = np.cos(rpy[:, 1]), np.sin(rpy[:, 1])
    cy, sy = np.cos(rpy[:, 2]), np.sin(rpy[:, 2])
    pd, yd = rate[:, 1], rate[:, 2]
    Ed = np.zeros_like(E)  # d/dt of E's entries
    Ed[:, 0, 0] = -sy * yd * cp - cy * sp * pd
    Ed[:, 1, 0] = cy * yd * cp - sy * sp * pd
    Ed[:, 2, 0] = -cp * pd
    Ed[:, 0, 1] = -cy * yd
    Ed[:, 1, 1] = -sy * yd
    w = np.einsum("nij,nj->ni", E, rate)
    alpha = np.einsum("nij,nj->ni", E, acc) + np.einsum("nij,nj->ni", Ed, rate)
    return (
        np.ascontiguousarray(q[:, :3]),
        rpy_to_matrix(rpy),
        np.ascontiguousarray(qd[:, :3]),
        w,
        np.ascontiguousarray(qdd[:, :3]),
        alpha,
    )


def margins(excitation: Excitation, model: Dynamics, times, per_sample: bool = False) -> np.ndarray:
    """Normalised margins to the platform's limits along the series, all >= 0 when it keeps
    within LIMIT_SHARE of each: leg stroke, workspace box, angle range, Jacobian condition number
    and leg force range (forces from ``model``'s inverse dynamics).  Five numbers (the smallest
    margin of each kind), or with ``per_sample`` every sample's margins, one vector.

    Args:
        excitation: the series.
        model: the dynamics model (its first platform's limits and inverse dynamics).
        times: the sample times (T,), s.
        per_sample: every sample's margins instead of the smallest of each kind.
    """
    p = model.params[0]
    lim = p.limits
    q, qd, qdd = excitation.sample(times)
    t, R, v, w, a, alpha = task_states(q, qd, qdd)
    lo, hi = lim.leg_length
    L, _ = inverse_kinematics(p, t, R)
    centre = 0.5 * (lim.position_min + lim.position_max)
    size = 0.5 * (lim.position_max - lim.position_min) * LIMIT_SHARE
    F = model.inverse(t, R, v, w, a, alpha)
    flo, fhi = lim.leg_force
    kinds = [
        1 - np.abs(L - 0.5 * (lo + hi)) / (0.5 * (hi - lo) * LIMIT_SHARE),
        1 - np.abs(t - centre) / size,
        1 - np.abs(q[:, 3:] - p.home_rpy) / (lim.max_angle * LIMIT_SHARE),
        1 - np.linalg.cond(jacobian(p, t, R))[:, None] / (lim.max_condition * LIMIT_SHARE),
        1 - np.abs(F - 0.5 * (flo + fhi)) / (0.5 * (fhi - flo) * LIMIT_SHARE),
    ]
    if per_sample:
        return np.concatenate([k.ravel() for k in kinds])
    return np.array([k.min() for k in kinds])


def condition_number(excitation: Excitation, model: Dynamics, base: BaseParameters, times) -> float:
    """Condition number of the base regressor stacked over the samples (leg-force rows:
    J^-T Y, the equations the estimators solve).

    Args:
        excitation: the series.
        model: the dynamics model (its first platform's limits and inverse dynamics).
        base: the base parameters.
        times: the sample times (T,), s.
    """
    q, qd, qdd = excitation.sample(times)
    states = task_states(q, qd, qdd)
    Y = reg.regressor_matrix(model, *states)
    J = jacobian(model.params[0], states[0], states[1])
    Yf = np.linalg.solve(np.swapaxes(J, 1, 2), base.columns(Y))
    return float(np.linalg.cond(Yf.reshape(-1, base.rank)))


def _from_vector(x, q0, H, wf):
    a, b = x.reshape(2, 6, H)
    return Excitation(q0, a, b, wf)


def random_excitation(
    params: PlatformParams,
    model: Dynamics,
    rng: np.random.Generator,
    period: float,
    harmonics: int = 5,
    samples: int = 100,
) -> Excitation:
    """A random series, scaled down until it keeps within the limits (:func:`margins` >= 0).

    Args:
        params: the platform: its home pose is q0 and its limits scale the amplitudes.
        model: the dynamics model (its first platform's limits and inverse dynamics).
        rng: the random generator.
        period: the series' period, s.
        harmonics: the number of harmonics H.
        samples: the samples per period the limits are checked at.
    """
    wf = 2 * math.pi / period
    q0 = np.concatenate([params.home_position, params.home_rpy])
    lim = params.limits
    # amplitude per coordinate: a quarter of the workspace half-width (m) or of the angle limit (rad)
    span = np.concatenate([0.5 * (lim.position_max - lim.position_min), np.full(3, lim.max_angle)])
    x = rng.normal(size=(2, 6, harmonics)) * (span * wf / 4)[None, :, None] / np.sqrt(harmonics)
    times = np.linspace(0, period, samples, endpoint=False)
    # the series at the start of the plant: q(0) = q0 shifts the constant part
    for scale in 0.7 ** np.arange(40):
        exc = _centred(_from_vector(scale * x.ravel(), q0, harmonics, wf))
        if np.all(margins(exc, model, times) >= 0):
            return exc
    raise IdentificationError(
        "excitation: no random series keeps within the platform's limits "
        "(leg stroke, workspace, condition number, leg forces) at the home pose"
    )


def _centred(exc: Excitation) -> Excitation:
    """The series shifted so that q(0) = q0 (the home pose)."""
    q, _, _ = exc.sample([0.0])
    return Excitation(exc.q0 - (q[0] - exc.q0), exc.a, exc.b, exc.wf)


def optimized_excitation(
    start: Excitation, model: Dynamics, base: BaseParameters, samples: int = 100, max_iterations: int = 30
) -> tuple[Excitation, dict]:
    """The series from ``start`` optimised (SLSQP) for the log condition number of the stacked
    base regressor, subject to :func:`margins` >= 0; the best feasible series met is kept (the
    start if none beats it).  Returns (excitation, info with the condition numbers).

    Args:
        start: the series the optimisation starts from.
        model: the dynamics model (its first platform's limits and inverse dynamics).
        base: the base parameters.
        samples: the samples per period the condition number and limits are evaluated at.
        max_iterations: SLSQP's iteration limit.
    """
    H, wf = start.harmonics, start.wf
    q_start = start.sample([0.0])[0][0]  # the pose at t = 0 stays the start's
    times = np.linspace(0, start.period, samples, endpoint=False)
    lim = model.params[0].limits
    # coefficients in units of the coordinate's range times wf: the optimiser sees numbers near 1
    span = np.concatenate([0.5 * (lim.position_max - lim.position_min), np.full(3, lim.max_angle)]) * wf
    scale = np.broadcast_to(span[None, :, None], (2, 6, H)).ravel()
    # the points of one iteration: SLSQP's finite differences of the objective and of the
    # constraints step to the same points, so each is computed once
    cache: dict[bytes, tuple[float, np.ndarray]] = {}
    cache_size = 4 * scale.size + 8
    best = {"value": np.inf, "x": None}

    def evaluate(z):
        key = z.tobytes()
        if key not in cache:
            exc = _centred_at(_from_vector(z * scale, start.q0, H, wf), q_start)
            value = math.log10(condition_number(exc, model, base, times))
            room = margins(exc, model, times, per_sample=True)
            if len(cache) >= cache_size:
                del cache[next(iter(cache))]  # the oldest point
            cache[key] = (value, room)
            if np.all(room >= 0) and value < best["value"]:
                best.update(value=value, x=z.copy())
        return cache[key]

    z0 = np.concatenate([start.a.ravel(), start.b.ravel()]) / scale
    before = 10 ** evaluate(z0)[0]
    try:
        result = scipy.optimize.minimize(
            lambda z: evaluate(z)[0],
            z0,
            method="SLSQP",
            constraints=[{"type": "ineq", "fun": lambda z: evaluate(z)[1]}],
            options={"maxiter": max_iterations, "ftol": 1e-4},
        )
        # SLSQP ends on the limits, often a little outside: shrink its series until it fits
        for shrink in 0.98 ** np.arange(1, 30):
            if np.all(evaluate(result.x * shrink)[1] >= 0):
                break
    except (ValueError, np.linalg.LinAlgError, FloatingPointError):
        pass  # a failed search leaves the best feasible series met so far
    exc = _centred_at(_from_vector(best["x"] * scale, start.q0, H, wf), q_start)
    return exc, {"condition_start": before, "condition": 10 ** best["value"]}


def _centred_at(exc: Excitation, q_start: np.ndarray) -> Excitation:
    q, _, _ = exc.sample([0.0])
    return Excitation(exc.q0 + (q_start - q[0]), exc.a, exc.b, exc.wf)
