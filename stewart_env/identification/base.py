"""The base parameters: the combinations of theta that the leg forces determine.

Many entries of theta never act alone on the leg forces (a lower leg's moment about its own axis
under C1, a lower leg's first moment along its axis, which only ever pairs with its inertia, ...)
or act only in fixed combinations.  :func:`base_parameters` finds them by QR with column pivoting
of a stacked regressor at random states: its rank r, r independent columns of theta (the
pivots), and for the other columns d the fixed combination ``beta = theta_i + K theta_d``
that each base parameter stands for.  The regressor of the base parameters is ``Y[:, :, i]``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from stewart_env.actuators.transmission import BallScrew
from stewart_env.dynamics.model import Dynamics
from stewart_env.errors import UsageError
from stewart_env.identification import regressor as reg
from stewart_env.params import Damping, PlatformParams, RigidBody
from stewart_env.rotations import rpy_to_matrix

#: Relative rank tolerance of the pivoted QR: a diagonal entry |R_kk| below this times |R_00| is a
#: numerical zero.  The regressor's entries are products of kernel terms known to a few units of
#: float64 rounding, so with a few thousand rows the columns that are combinations of others show
#: |R_kk| / |R_00| near 1e-13 and the identifiable ones above 1e-6 (the gap the tests check).
RANK_TOLERANCE = 1e-9


class IdentificationError(UsageError):
    """Identification cannot go on: the data or a setting does not allow it (the message names
    the cause)."""


@dataclass(frozen=True)
class BaseParameters:
    """The base parameters of a model on a platform's geometry.

    Attributes:
        independent: (r,) indices into theta of the base parameters' leading columns.
        dependent: (N_THETA - r,) indices of the other columns.
        combination: (r, N_THETA - r) K: base parameter k = theta[independent[k]] + K[k] @ theta[dependent].
        diagonal: (N_THETA,) |R_kk| / |R_00| of the pivoted QR, in pivot order (the rank's evidence).
        flags: the model's switch bits (theta's inertias depend on them, see regressor.theta_of).
    """

    independent: np.ndarray
    dependent: np.ndarray
    combination: np.ndarray
    diagonal: np.ndarray
    flags: int

    @property
    def rank(self) -> int:
        """The number r of base parameters."""
        return int(self.independent.size)

    @property
    def names(self) -> list[str]:
        """Each base parameter as the combination of theta it stands for, e.g.
        ``"lower_leg[0].Iyy + 0.5*lower_leg[0].Izz"`` (coefficients under 1e-10 left out)."""
        out = []
        for k, i in enumerate(self.independent):
            terms = [reg.THETA_NAMES[i]]
            for c, j in zip(self.combination[k], self.dependent):
                if abs(c) > 1e-10:
                    terms.append(f"{'-' if c < 0 else '+'} {abs(c):.6g}*{reg.THETA_NAMES[j]}")
            out.append(" ".join(terms))
        return out

    def of_theta(self, theta: np.ndarray) -> np.ndarray:
        """Base parameters (r,) of a full theta (N_THETA,).

        Args:
            theta: the full inertial and friction parameters theta (N_THETA,) of
                :mod:`~stewart_env.identification.regressor`.
        """
        theta = np.asarray(theta, float)
        return theta[self.independent] + self.combination @ theta[self.dependent]

    def columns(self, Y: np.ndarray) -> np.ndarray:
        """The base regressor: the independent columns of Y (..., N_THETA) -> (..., r).

        Args:
            Y: the regressor (..., N_THETA) of :func:`~stewart_env.identification.regressor.regressor_matrix`.
        """
        return Y[..., self.independent]

    def theta_from(self, beta: np.ndarray, nominal_theta: np.ndarray) -> np.ndarray:
        """A full theta with base parameters beta: the dependent entries from the nominal theta
        (they are not identifiable), the independent ones solved from beta.

        Args:
            beta: the base parameters (r,).
            nominal_theta: the nominal platform's full theta (N_THETA,).
        """
        theta = np.array(nominal_theta, float)
        theta[self.independent] = np.asarray(beta, float) - self.combination @ theta[self.dependent]
        return theta


def random_states(params: PlatformParams, n: int, rng: np.random.Generator, speed: float = 0.5):
    """N random states inside the platform's workspace box and angle limit (t, R, v, w, a, alpha).

    Args:
        params: the platform, whose limits bound the poses.
        n: the number of states.
        rng: the random generator.
        speed: the standard deviation of each velocity component, m/s (twice it for the angular velocity,
            rad/s).
    """
    lim = params.limits
    t = rng.uniform(lim.position_min, lim.position_max, size=(n, 3))
    rpy = params.home_rpy + rng.uniform(-lim.max_angle, lim.max_angle, size=(n, 3)) * 0.5
    R = np.stack([rpy_to_matrix(x) for x in rpy])
    v = rng.normal(scale=speed, size=(n, 3))
    w = rng.normal(scale=2 * speed, size=(n, 3))
    return t, R, v, w, rng.normal(scale=2.0, size=(n, 3)), rng.normal(scale=4.0, size=(n, 3))


def stacked_regressor(model: Dynamics, states) -> np.ndarray:
    """Y of each state stacked into one (6 N, N_THETA) matrix.

    Args:
        model: the dynamics model.
        states: the states (t, R, v, w, a, alpha), each (N, ...), as :func:`random_states` gives them.
    """
    return reg.regressor_matrix(model, *states).reshape(-1, reg.N_THETA)


def base_parameters(model: Dynamics, n_states: int = 400, seed: int = 0) -> BaseParameters:
    """The base parameters of ``model`` (its first platform's geometry and gravity), from the
    pivoted QR of Y stacked over ``n_states`` random states (:data:`RANK_TOLERANCE`).

    Args:
        model: the dynamics model.
        n_states: the number of random states Y is stacked over.
        seed: the seed of those states.
    """
    states = random_states(model.params[0], n_states, np.random.default_rng(seed))
    W = stacked_regressor(model, states)
    _, R, piv = scipy.linalg.qr(W, mode="economic", pivoting=True)
    d = np.abs(np.diag(R))
    rel = d / d[0]
    r = int(np.sum(rel > RANK_TOLERANCE))
    K = scipy.linalg.solve_triangular(R[:r, :r], R[:r, r:])
    K[np.abs(K) < 1e-12 * max(1.0, np.abs(K).max())] = 0.0
    rows = np.argsort(piv[:r])  # base parameters in theta's order, for reading
    cols = np.argsort(piv[r:])
    return BaseParameters(
        independent=piv[:r][rows],
        dependent=piv[r:][cols],
        combination=K[rows][:, cols],
        diagonal=rel,
        flags=model.flags,
    )


def params_from_theta(
    theta: np.ndarray, nominal: PlatformParams, flags: int, name: str | None = None, drive: bool = False
) -> PlatformParams:
    """The platform of a full theta, on the nominal's geometry, limits and home pose.

    With ``drive`` (the forces were the drives', from motor currents) and a nominal with an
    electric drive, theta's Coulomb friction, reflected mass (as the rotor inertia m_r / k^2) and
    the viscous friction beyond the nominal joint's C_p go into ``actuators.electric``; otherwise
    the drive's entries stay in theta only (the report shows them) and C_p takes the whole viscous
    leg friction.

    Raises IdentificationError naming the body when theta does not describe a real body (a
    mass <= 0, or an inertia about the CoM that is not positive semidefinite): use a physically
    consistent estimate (:func:`stewart_env.identification.estimate.consistent`).

    Args:
        theta: the full theta (N_THETA,).
        nominal: the nominal platform, whose geometry, limits and home pose are kept.
        flags: the model's switch bits (theta's inertias depend on them).
        name: the new platform's name (default the nominal's).
        drive: theta is of the drives' forces (see above).

    Returns:
        The platform.

    Raises:
        IdentificationError: theta is not of a real body, or a friction or reflected mass is negative.
    """
    leg_shift, plat_shift = reg.shifts_of(flags)

    def body(k: int, shifts: float, label: str, positive: bool) -> RigidBody:
        m, com, inertia = reg.body_from_theta(theta[k : k + reg.N_BODY], shifts)
        if not np.isfinite(m) or m <= 0 and positive or m < 0:
            raise IdentificationError(f"identified {label}: mass {m:.6g} kg is not a body's mass")
        if m == 0:
            return RigidBody(mass=0.0, com=np.zeros(3), inertia=np.zeros((3, 3)))
        try:
            return RigidBody(mass=m, com=com, inertia=inertia)
        except ValueError as err:
            raise IdentificationError(f"identified {label}: {err}") from None

    platform = body(0, plat_shift, "platform", True)
    upper, lower = [], []
    for i in range(6):
        k = reg.N_BODY * (1 + 2 * i)
        upper.append(body(k, leg_shift, f"upper_leg[{i}]", False))
        lower.append(body(k + reg.N_BODY, leg_shift, f"lower_leg[{i}]", False))
    cu, cp, cs = (float(x) for x in theta[reg.OFF_DAMPING : reg.OFF_DAMPING + 3])
    fc, mr = (float(x) for x in theta[reg.OFF_DRIVE : reg.OFF_DRIVE + 2])
    if min(cu, cp, cs) < 0:
        raise IdentificationError(f"identified damping ({cu:.4g}, {cp:.4g}, {cs:.4g}) has a negative coefficient")
    if min(fc, mr) < 0:
        raise IdentificationError(
            f"identified drive: Coulomb friction {fc:.4g} N and reflected mass {mr:.4g} kg must be >= 0"
        )
    actuators = nominal.actuators
    electric = actuators.electric
    if drive and electric is not None:
        # C_p and the drive's viscous b act alike: the joint keeps its nominal share, the drive the rest
        b = cp - nominal.damping.prismatic
        cp, b = (nominal.damping.prismatic, b) if b >= 0 else (cp, 0.0)
        ratio = BallScrew.from_params(electric).ratio
        electric = dataclasses.replace(electric, viscous_friction=b, coulomb_friction=fc, rotor_inertia=mr / ratio**2)
        actuators = dataclasses.replace(actuators, electric=electric)
    return nominal.replace(
        name=name or nominal.name,
        platform=platform,
        upper_leg=tuple(upper),
        lower_leg=tuple(lower),
        damping=Damping(cu, cp, cs),
        actuators=actuators,
    )
