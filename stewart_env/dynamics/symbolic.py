"""The symbolic model: the forward dynamics and one control step as CasADi functions (extra ``casadi``).

Each function is a ``casadi.Callback`` around the compiled kernels: its value is the kernel's
(:meth:`~stewart_env.dynamics.Dynamics.forward`, or :func:`stewart_env.rollout` for the step, bit
for bit) and its Jacobian the exact one of :meth:`~stewart_env.dynamics.Dynamics.acceleration_jacobians`
and :meth:`~stewart_env.dynamics.Dynamics.step_jacobians`, so that an optimal control problem
written in CasADi (an NMPC with IPOPT, say) uses the same model as the simulator, with no second
implementation of any equation.  No second derivatives: ask IPOPT for
``hessian_approximation="limited-memory"``.

The state.  A CasADi variable is a vector, so the rotation enters as its rotation vector theta,
R = exp([theta]x) (:func:`stewart_env.rotations.rotvec_to_matrix`): x = (t, theta, v, w) in R^12,
t the position of P's origin (m), v its velocity (m/s), w the angular velocity (rad/s), all in
{B}.  The compiled Jacobians are taken in the tangent coordinates (dt, dtheta, v, w), dtheta a
rotation applied on the left (:mod:`stewart_env.dynamics.derivatives`); the chain rule through
exp gives them in theta: exp([theta + d theta]x) = exp([J_l(theta) d theta]x) exp([theta]x) to
first order, J_l the left Jacobian of SO(3) (:func:`left_jacobian`), and the next rotation vector
moves by J_l(theta')^-1 dtheta'.  The parameterisation is regular for |theta| < pi (a platform
turns far less); at |theta| = pi it is singular.

Keep a reference to a returned function while CasADi uses it: it is a Python object that CasADi
calls back.
"""

from __future__ import annotations

import numpy as np

from stewart_env import validation
from stewart_env.dynamics.model import Dynamics
from stewart_env.extras import require
from stewart_env.rotations import rotation_error, rotvec_to_matrix

__all__ = ["control_step_function", "forward_dynamics_function", "left_jacobian", "left_jacobian_inverse"]

#: Below this angle (rad) the left Jacobian's coefficients are taken from their series, where the
#: quotients lose digits: their next terms are O(angle^4) ~ 1e-24, below rounding.
_SMALL_ANGLE = 1e-6


def _skew(phi: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -phi[2], phi[1]], [phi[2], 0.0, -phi[0]], [-phi[1], phi[0], 0.0]])


def left_jacobian(theta) -> np.ndarray:
    """The left Jacobian of SO(3): exp([theta + d]x) = exp([J_l(theta) d]x) exp([theta]x) to first order.

    J_l = I + (1 - cos a) / a^2 [theta]x + (a - sin a) / a^3 [theta]x^2, a = |theta|.

    Args:
        theta: (3,) a rotation vector, rad.

    Returns:
        J_l (3,3).
    """
    theta = np.asarray(theta, dtype=float)
    a = float(np.linalg.norm(theta))
    k = _skew(theta)
    if a < _SMALL_ANGLE:
        c1, c2 = 0.5 - a**2 / 24, 1.0 / 6 - a**2 / 120
    else:
        c1, c2 = (1 - np.cos(a)) / a**2, (a - np.sin(a)) / a**3
    return np.eye(3) + c1 * k + c2 * k @ k


def left_jacobian_inverse(theta) -> np.ndarray:
    """The inverse of :func:`left_jacobian`: I - [theta]x / 2 + (1/a^2 - (1 + cos a) / (2 a sin a)) [theta]x^2.

    Args:
        theta: (3,) a rotation vector, rad, |theta| < pi.

    Returns:
        J_l^-1 (3,3).
    """
    theta = np.asarray(theta, dtype=float)
    a = float(np.linalg.norm(theta))
    k = _skew(theta)
    c2 = 1.0 / 12 + a**2 / 720 if a < _SMALL_ANGLE else 1 / a**2 - (1 + np.cos(a)) / (2 * a * np.sin(a))
    return np.eye(3) - 0.5 * k + c2 * k @ k


def _casadi():
    require("casadi", "the symbolic model (stewart_env.dynamics.symbolic)")
    import casadi

    return casadi


def _check_model(model) -> Dynamics:
    if not isinstance(model, Dynamics):
        raise ValueError(f"model: expected a Dynamics, got {type(model).__name__}")
    if len(model.params) != 1:
        raise ValueError(f"model: expected one platform, got {len(model.params)} parameter rows")
    return model


def _unpack(x: np.ndarray):
    """(t, R, v, w) of a state vector (t, theta, v, w), R = exp([theta]x)."""
    x = np.asarray(x, dtype=float).reshape(12)
    return x[0:3], rotvec_to_matrix(x[3:6]), x[6:9], x[9:12]


def _chain_in(x: np.ndarray) -> np.ndarray:
    """The Jacobian of (dt, dtheta_left, v, w) by (t, theta, v, w) at x: I but the rotation block J_l(theta)."""
    out = np.eye(12)
    out[3:6, 3:6] = left_jacobian(np.asarray(x, dtype=float).reshape(12)[3:6])
    return out


def _make_callback(casadi, name: str, n_out: int, value, jacobians, opts):
    """A casadi.Callback (x (12), F (6)) -> y (n_out) of ``value(x, F)``, with the Jacobian
    callback of ``jacobians(x, F) -> (dy/dx, dy/dF)``."""

    class _Jacobian(casadi.Callback):
        # CasADi's Jacobian function: inputs x, F and the nominal output; outputs dy/dx, dy/dF
        def __init__(self, jac_name, jac_opts):
            casadi.Callback.__init__(self)
            self.construct(jac_name, jac_opts)

        def get_n_in(self):
            return 3

        def get_n_out(self):
            return 2

        def get_sparsity_in(self, i):
            return casadi.Sparsity.dense((12, 6, n_out)[i], 1)

        def get_sparsity_out(self, i):
            return casadi.Sparsity.dense(n_out, (12, 6)[i])

        def eval(self, arg):
            d_x, d_f = jacobians(np.asarray(arg[0]).ravel(), np.asarray(arg[1]).ravel())
            return [casadi.DM(d_x), casadi.DM(d_f)]

    class _Function(casadi.Callback):
        def __init__(self):
            casadi.Callback.__init__(self)
            self._jacobian = None  # kept alive with the function: CasADi calls back into it
            self.construct(name, dict(opts))

        def get_n_in(self):
            return 2

        def get_n_out(self):
            return 1

        def get_name_in(self, i):
            return ("x", "leg_forces")[i]

        def get_name_out(self, i):
            return "y"

        def get_sparsity_in(self, i):
            return casadi.Sparsity.dense((12, 6)[i], 1)

        def get_sparsity_out(self, i):
            return casadi.Sparsity.dense(n_out, 1)

        def eval(self, arg):
            return [casadi.DM(value(np.asarray(arg[0]).ravel(), np.asarray(arg[1]).ravel()))]

        def has_jacobian(self):
            return True

        def get_jacobian(self, jac_name, inames, onames, jac_opts):
            self._jacobian = _Jacobian(jac_name, jac_opts)
            return self._jacobian

    return _Function()


def forward_dynamics_function(model: Dynamics, name: str = "forward_dynamics", opts=None):
    """The forward dynamics as a CasADi function (x, leg_forces) -> (a, alpha).

    x = (t, theta, v, w) (12,) as in the module docstring; leg_forces (6,) in N; the output (6,)
    the acceleration of P's origin (m/s^2) and the angular acceleration (rad/s^2), {B}, as
    :meth:`~stewart_env.dynamics.Dynamics.forward` gives them.  Its Jacobian is the compiled
    kernel's (:meth:`~stewart_env.dynamics.Dynamics.acceleration_jacobians`) in these coordinates.

    Args:
        model: the dynamics model, one platform.
        name: the function's name in CasADi.
        opts: options of the CasADi function (a dict), or None.

    Returns:
        A ``casadi.Function`` (a ``casadi.Callback``); keep a reference while CasADi uses it.

    Raises:
        ValueError: ``model`` not a Dynamics of one platform.
        stewart_env.extras.MissingExtra: casadi is not installed (the extra ``casadi``).

    Examples:
        >>> import numpy as np, stewart_env as se
        >>> from stewart_env.dynamics.symbolic import forward_dynamics_function
        >>> params = se.load_platform("dasgupta1998")
        >>> model = se.make_dynamics("improved", params)
        >>> f = forward_dynamics_function(model)
        >>> x = np.concatenate([params.home_position, np.zeros(9)])
        >>> holding = model.inverse(params.home_position, np.eye(3), np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3))
        >>> bool(np.abs(np.array(f(x, holding))).max() < 1e-9)
        True
    """
    casadi = _casadi()
    model = _check_model(model)

    def value(x, forces):
        return np.concatenate(model.forward(*_unpack(x), forces))

    def jacobians(x, forces):
        jac = model.acceleration_jacobians(*_unpack(x), forces)
        d_x = np.hstack([jac.d_pose, jac.d_twist]) @ _chain_in(x)
        return d_x, jac.d_forces

    return _make_callback(casadi, name, 6, value, jacobians, opts or {})


def control_step_function(model: Dynamics, dt: float, steps: int = 1, name: str = "control_step", opts=None):
    """One control step as a CasADi function (x, leg_forces) -> x_next.

    ``steps`` RK4 substeps of ``dt / steps`` s with the leg forces held (the integrator of
    :func:`stewart_env.rollout` and of the environment: ``dt`` its ``control_dt``, ``steps`` its
    ``substeps``); x and x_next are (t, theta, v, w) (12,) as in the module docstring, x_next's
    rotation vector that of the next rotation (|theta| < pi).  Its Jacobian is the compiled
    kernel's (:meth:`~stewart_env.dynamics.Dynamics.step_jacobians`) in these coordinates.

    Args:
        model: the dynamics model, one platform.
        dt: the control step, s (> 0).
        steps: the RK4 substeps (>= 1).
        name: the function's name in CasADi.
        opts: options of the CasADi function (a dict), or None.

    Returns:
        A ``casadi.Function`` (a ``casadi.Callback``); keep a reference while CasADi uses it.

    Raises:
        ValueError: ``model`` not a Dynamics of one platform, or a bad ``dt`` or ``steps``.
        stewart_env.extras.MissingExtra: casadi is not installed (the extra ``casadi``).
    """
    from stewart_env.integrate import rollout

    casadi = _casadi()
    model = _check_model(model)
    dt = validation.real("dt", dt, 0.0, np.inf, low_open=True)
    steps = validation.integer("steps", steps, 1, 10**6)

    def state_vector(position, rotation, velocity, angular_velocity):
        theta = rotation_error(rotation, np.eye(3))[0]
        return np.concatenate([position, theta, velocity, angular_velocity])

    def value(x, forces):
        return state_vector(*rollout(model, *_unpack(x), forces, dt=dt / steps, steps=steps))

    def jacobians(x, forces):
        out = model.step_jacobians(*_unpack(x), forces, dt, steps)
        if not out.finite:
            raise FloatingPointError("control step: the state stopped being finite (a singular pose)")
        x_next = state_vector(*out.state)
        chain_out = np.eye(12)
        chain_out[3:6, 3:6] = left_jacobian_inverse(x_next[3:6])
        return chain_out @ out.A @ _chain_in(x), chain_out @ out.B

    return _make_callback(casadi, name, 12, value, jacobians, opts or {})
