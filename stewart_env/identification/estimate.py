"""Estimators: motion derivatives from noisy poses, ordinary and weighted least squares with
standard deviations, and a physically consistent estimate.

The equations are written in leg-force space: with A = J^-T Y_base (rows one per leg and sample)
the measured leg forces are F = A beta + noise.  Noise on the measured forces is then noise on the
rows themselves, so the least-squares covariance sigma^2 (A^T A)^-1 is the estimate's own
(errors in the regressor from filtered positions are not in it: the report's comparison with the
truth shows them).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.optimize
import scipy.signal

from stewart_env.identification import regressor as reg
from stewart_env.identification.base import BaseParameters, IdentificationError

#: Savitzky-Golay filter: polynomial order and window length (samples, odd) of the default.
SAVGOL_ORDER = 3
SAVGOL_WINDOW = 21
#: The relative standard deviation under which the literature calls a parameter well identified.
WELL_IDENTIFIED = 0.1
#: An estimate within this many of its standard deviations of zero is not told from zero.
NEAR_ZERO_STD = 2.0
#: The consistent fit's prior weight relative to the data's largest singular value.  It pulls the
#: base parameters the excitation hardly moves toward the nominal's values: a weaker prior fits
#: held-out forces better but tracks a machine near the nominal worse (docs/guides/your-own-platform.md).
PRIOR_WEIGHT = 1e-3
#: The consistent fit's limit on its residual evaluations (beyond the Jacobian's).
CONSISTENT_MAX_NFEV = 100


def _vee(S: np.ndarray) -> np.ndarray:
    """The vector of the skew part of S (..., 3, 3)."""
    return 0.5 * np.stack([S[..., 2, 1] - S[..., 1, 2], S[..., 0, 2] - S[..., 2, 0], S[..., 1, 0] - S[..., 0, 1]], -1)


def derivatives(
    dt: float, position: np.ndarray, rotation: np.ndarray, window: int = SAVGOL_WINDOW, order: int = SAVGOL_ORDER
):
    """(t, R, v, w, a, alpha) from poses sampled every ``dt`` s, by a Savitzky-Golay filter
    (``scipy.signal.savgol_filter``, polynomial ``order`` over ``window`` samples, its zeroth,
    first and second derivatives).  The rotation's nine entries are filtered alike and the
    smoothed matrix taken back to the nearest rotation (polar decomposition); omega and alpha are
    the skew parts of Rdot R^T and Rddot R^T ({B}).  The first and last window // 2 samples are
    the filter's own extrapolation: callers drop them.

    Args:
        dt: the sampling interval, s.
        position: the sampled positions t (T, 3) of P's origin in {B}, m.
        rotation: the sampled rotations R (T, 3, 3) of {P} in {B}.
        window: the filter's window, samples (odd).
        order: the filter's polynomial order.
    """
    n = position.shape[0]
    if window % 2 == 0 or window <= order or n < window:
        raise IdentificationError(f"filter: {n} samples are too few for a window of {window} (odd, > order {order})")

    def sg(x, d):
        return scipy.signal.savgol_filter(x, window, order, deriv=d, delta=dt, axis=0, mode="interp")

    t, v, a = sg(position, 0), sg(position, 1), sg(position, 2)
    flat = rotation.reshape(n, 9)
    Rs, Rd, Rdd = (sg(flat, d).reshape(n, 3, 3) for d in (0, 1, 2))
    U, _, Vt = np.linalg.svd(Rs)
    R = U @ Vt
    Rt = np.swapaxes(R, 1, 2)
    return t, R, v, _vee(Rd @ Rt), a, _vee(Rdd @ Rt)


@dataclass(frozen=True)
class Estimate:
    """A least-squares estimate of the base parameters: beta (r,), std (r,) its standard
    deviations, sigma (6,) the residual standard deviation of each leg's force (N), and cov (r, r)."""

    beta: np.ndarray
    std: np.ndarray
    sigma: np.ndarray
    cov: np.ndarray


def leg_force_rows(Y_base: np.ndarray, J: np.ndarray) -> np.ndarray:
    """A = J^-T Y_base (T, 6, r): leg i's force row of each sample.

    Args:
        Y_base: the base regressor (T, 6, r) of each sample.
        J: the leg Jacobian (T, 6, 6) of each sample.
    """
    return np.linalg.solve(np.swapaxes(J, 1, 2), Y_base)


def check_rank(A: np.ndarray, base: BaseParameters) -> None:
    """Raise IdentificationError when the stacked rows cannot determine every base parameter.

    Args:
        A: the leg force rows (T, 6, r).
        base: the base parameters the rows are of.
    """
    rows = A.reshape(-1, A.shape[-1])
    if rows.shape[0] <= rows.shape[1]:
        raise IdentificationError(
            f"data: {rows.shape[0]} equations for {rows.shape[1]} base parameters; record longer (--duration)"
        )
    d = np.abs(np.diag(scipy.linalg.qr(rows, mode="r", pivoting=True)[0]))
    if d[-1] < 1e-10 * d[0]:
        weak = int(np.sum(d < 1e-10 * d[0]))
        raise IdentificationError(
            f"data: rank-deficient, {weak} of {rows.shape[1]} base parameters are not "
            "excited by this trajectory; record longer or use --excitation optimized"
        )


def ols(A: np.ndarray, F: np.ndarray) -> Estimate:
    """Ordinary least squares of F (T, 6) = A (T, 6, r) beta, with the standard deviations from
    one common residual variance.

    Args:
        A: the leg force rows (T, 6, r) of :func:`leg_force_rows`.
        F: the measured leg forces (T, 6), N.
    """
    rows, y = A.reshape(-1, A.shape[-1]), F.ravel()
    beta, *_ = np.linalg.lstsq(rows, y, rcond=None)
    res = (y - rows @ beta).reshape(F.shape)
    dof = rows.shape[0] - rows.shape[1]
    s2 = float(np.sum(res**2) / dof)
    cov = s2 * np.linalg.inv(rows.T @ rows)
    return Estimate(beta, np.sqrt(np.diag(cov)), np.sqrt(np.mean(res**2, axis=0)), cov)


def wls(A: np.ndarray, F: np.ndarray) -> Estimate:
    """Weighted least squares: each leg's equations weighted by the inverse of that leg's
    residual standard deviation in the ordinary estimate (Gautier's two-step WLS), with the
    covariance (A^T W A)^-1.

    Args:
        A: the leg force rows (T, 6, r) of :func:`leg_force_rows`.
        F: the measured leg forces (T, 6), N.
    """
    first = ols(A, F)
    T = F.shape[0]
    dof = (T * 6 - A.shape[-1]) / 6  # residual degrees of freedom per leg
    sigma = np.sqrt(np.sum((F - np.einsum("tir,r->ti", A, first.beta)) ** 2, axis=0) / dof)
    if np.any(sigma <= 0):
        return first  # noise-free data: every weight equal
    Aw, yw = A / sigma[None, :, None], F / sigma[None, :]
    rows, y = Aw.reshape(-1, A.shape[-1]), yw.ravel()
    beta, *_ = np.linalg.lstsq(rows, y, rcond=None)
    res = F - np.einsum("tir,r->ti", A, beta)
    cov = np.linalg.inv(rows.T @ rows)
    return Estimate(beta, np.sqrt(np.diag(cov)), np.sqrt(np.mean(res**2, axis=0)), cov)


@dataclass(frozen=True)
class Requirement:
    """What brings each base parameter to a relative standard deviation ``target``: rel_std (r,)
    now (std / |beta|), duration (r,) the record (s) at the same noise, noise (r,) the force noise
    (N) in the same record, and near_zero (r,) where beta is within NEAR_ZERO_STD standard
    deviations of zero (there the relative deviation, and so the two answers, tell nothing)."""

    rel_std: np.ndarray
    duration: np.ndarray
    noise: np.ndarray
    near_zero: np.ndarray


def requirements(
    beta: np.ndarray, std: np.ndarray, duration: float, noise: float, target: float = WELL_IDENTIFIED
) -> Requirement:
    """Recording time and force noise for a relative standard deviation ``target``, per base
    parameter, from one estimate (beta, std) of a ``duration``-second record at force noise
    ``noise`` (N).  Under white force noise sigma the least-squares covariance is
    sigma^2 (A^T A)^-1 and A^T A grows linearly with the record of a periodic excitation, so
    std_k ~ sigma / sqrt(T):  T_k = T (RSD_k / target)^2  at the same noise and
    sigma_k = sigma target / RSD_k  in the same record.  A zero estimate needs an infinite
    record; without noise (``noise`` 0) the noise answer is infinite too.

    Args:
        beta: the estimated base parameters (r,).
        std: their standard deviations (r,).
        duration: the record's length, s.
        noise: the force noise of the record, N.
        target: the relative standard deviation asked for.
    """
    beta, std = np.asarray(beta, float), np.asarray(std, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.where(beta != 0, np.abs(std) / np.abs(beta), np.inf)
        ratio = rel / target
        time = duration * ratio**2
        sigma = np.where(noise > 0, noise / ratio, np.inf)
    return Requirement(rel, time, sigma, np.abs(beta) <= NEAR_ZERO_STD * np.abs(std))


def predicted_std(std: np.ndarray, duration: float, noise: float, to_duration: float, to_noise: float) -> np.ndarray:
    """The standard deviations (as :func:`requirements` scales them, std ~ sigma / sqrt(T)) that
    estimates of std from a ``duration``-second record at force noise ``noise`` predict for a
    ``to_duration``-second record at ``to_noise`` along the same excitation.

    Args:
        std: the estimate's standard deviations (r,).
        duration: the estimate's record length, s.
        noise: the estimate's force noise, N.
        to_duration: the predicted record's length, s.
        to_noise: the predicted record's force noise, N.
    """
    return np.asarray(std, float) * (to_noise / noise) * np.sqrt(duration / to_duration)


def _physical_body(phi: np.ndarray, shifts: float) -> np.ndarray:
    """A body's 10 parameters from mass phi0 (>= 0 by the solver's bounds), first moment phi1:4
    and the lower triangle L of the CoM's second moment Sigma = L L^T (phi4:10): the inertia about
    the CoM, tr(Sigma) E - Sigma, is then positive semidefinite and its principal moments satisfy
    the triangle inequalities, those of a real mass distribution."""
    m = max(phi[0], 1e-12)
    L = np.zeros((3, 3))
    L[np.tril_indices(3)] = phi[4:10]
    S = L @ L.T
    return reg.body_theta(m, phi[1:4] / m, np.trace(S) * np.eye(3) - S, shifts)


def _physical_of(theta_body: np.ndarray, shifts: float, mass_floor: float) -> np.ndarray:
    """The numbers of :func:`_physical_body` of the nearest real body to 10 parameters (mass at
    least ``mass_floor``, second moment clipped to positive semidefinite)."""
    m, com, inertia = reg.body_from_theta(theta_body, shifts)
    if not m >= mass_floor:
        m, com = mass_floor, np.zeros(3)
    S = 0.5 * np.trace(inertia) * np.eye(3) - inertia
    w, V = np.linalg.eigh(0.5 * (S + S.T))
    S = (V * np.maximum(w, 1e-12 + 1e-6 * max(w.max(), 0.0))) @ V.T
    L = np.linalg.cholesky(S)
    return np.concatenate([[m], m * com, L[np.tril_indices(3)]])


def consistent(
    A: np.ndarray,
    F: np.ndarray,
    base: BaseParameters,
    nominal_theta: np.ndarray,
    start_theta: np.ndarray,
    prior_weight: float = PRIOR_WEIGHT,
    sigma: np.ndarray | None = None,
    max_nfev: int = CONSISTENT_MAX_NFEV,
) -> np.ndarray:
    """A physically consistent full theta: positive masses, inertias of real bodies (see
    :func:`_physical_body`), non-negative friction and reflected mass, fitting the leg forces in
    the (weighted) least-squares sense (``scipy.optimize.least_squares`` with bounds, run to
    convergence).  The directions the data do not determine are held near the nominal theta by a
    prior of weight ``prior_weight`` relative to the data's largest singular value: so weak that
    it moves no base parameter the data determine (a stronger one pulls the poorly excited base
    parameters to the nominal's values, a bias the held-out forces show).

    Args:
        A: the leg force rows (T, 6, r) of :func:`leg_force_rows`.
        F: the measured leg forces (T, 6), N.
        base: the base parameters of the rows.
        nominal_theta: the nominal platform's full theta (N_THETA,), the prior.
        start_theta: the full theta the solver starts from.
        prior_weight: the prior's weight relative to the data's largest singular value.
        sigma: (6,) each leg's force noise, N, whose inverse weights its equations, as
            :func:`wls` does (None, or a zero: equal weights).
        max_nfev: the solver's limit on its evaluations.

    Returns:
        The full theta (N_THETA,).
    """
    if sigma is not None and np.all(np.asarray(sigma) > 0):
        A, F = A / sigma[None, :, None], F / sigma[None, :]
    rows, y = A.reshape(-1, A.shape[-1]), F.ravel()
    # the data term through the triangular factor: |rows beta - y|^2 = |R beta - Q^T y|^2 + const
    Q, R = np.linalg.qr(rows)
    qy = Q.T @ y
    leg_shift, plat_shift = reg.shifts_of(base.flags)
    shifts = [plat_shift] + [leg_shift] * 12
    n_body = 13 * reg.N_BODY
    scale_theta = np.maximum(np.abs(nominal_theta), 1e-3 * np.abs(nominal_theta).max())
    weight = prior_weight * np.linalg.norm(R, 2)
    # beta = P theta, so the data term is linear in theta: B theta - Q^T y with B = R P
    P = np.zeros((base.rank, reg.N_THETA))
    P[np.arange(base.rank), base.independent] = 1.0
    P[:, base.dependent] = base.combination
    B = R @ P
    prior = weight / scale_theta

    def theta_of(phi):
        bodies = [_physical_body(phi[10 * k : 10 * k + 10], shifts[k]) for k in range(13)]
        return np.concatenate(bodies + [phi[n_body:]])

    def residual(phi):
        theta = theta_of(phi)
        return np.concatenate([B @ theta - qy, prior * (theta - nominal_theta)])

    def jac(phi):
        # theta's body k depends on phi's body k only: d theta / d phi is block diagonal, each
        # 10 x 10 block by central differences of one body (the friction and drive entries: identity)
        D = np.eye(reg.N_THETA)
        for k in range(13):
            p = phi[10 * k : 10 * k + 10]
            for j in range(10):
                h = 1e-7 * max(abs(p[j]), 1e-3)
                up, down = p.copy(), p.copy()
                up[j] += h
                down[j] -= h
                D[10 * k : 10 * k + 10, 10 * k + j] = (
                    _physical_body(up, shifts[k]) - _physical_body(down, shifts[k])
                ) / (2 * h)
        return np.vstack([B @ D, prior[:, None] * D])

    floors = [1e-3 * max(nominal_theta[10 * k], 1e-3) for k in range(13)]
    phi0 = np.concatenate(
        [_physical_of(start_theta[10 * k : 10 * k + 10], shifts[k], floors[k]) for k in range(13)]
        + [np.maximum(start_theta[n_body:], 0.0)]
    )
    lower = np.full(reg.N_THETA, -np.inf)
    lower[0:n_body:10] = 0.0
    lower[n_body:] = 0.0  # joint friction, the drive's friction and reflected mass
    phi0 = np.maximum(phi0, lower + 1e-12)
    x_scale = np.maximum(np.abs(phi0), 1e-3 * np.abs(phi0).max())
    result = scipy.optimize.least_squares(
        residual, phi0, jac=jac, bounds=(lower, np.inf), method="trf", x_scale=x_scale, max_nfev=max_nfev
    )
    return theta_of(result.x)
