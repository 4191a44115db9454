"""Control laws for the one RK4 integrator: compiled C functions evaluated at every RK4 stage.

The integrator itself is C++ (``stewart_env/_core/cpp/physics/rk4.hpp``, docs/physics.md section 5.6).
A control law is a C function that returns nothing and writes six leg forces::

    void law(double time, const double *position, const double *rotation, const double *velocity,
             const double *angular_velocity, const double *params, int64_t n_params, double *forces);

time (s); position (3,), rotation (3,3, row-major), velocity (3,), angular_velocity (3,): the
stage's state in {B}, to be read only; params (n_params,): the law's own parameter row (gains,
targets, ... in a layout the law defines); forces (6,): the leg forces, N, positive extending the
leg, each NaN until the law writes it.  The law runs without Python's GIL.

A :class:`ControlLaw` wraps such a function for :func:`stewart_env.rollout`.  Three sources:

* the package's compiled laws: :data:`PD_CONTROL_LAW` (the task-space PD law of He et al. 2018,
  eq. 56, parameter layout :data:`PD_LAYOUT`) and :data:`CONSTANT_FORCES` (forces = params[:6]);
* a numba ``cfunc`` compiled for :func:`numba_law_signature` (numba is the optional extra
  ``laws``: ``pip install -e ".[laws]"`` from a clone);
* a ctypes function of type :data:`LAW_CTYPES`, e.g. from a shared library of your own:
  ``ctypes.cast(lib.my_law, LAW_CTYPES)``.

Inside a law, :data:`jacobian` and :data:`inverse_dynamics` (ctypes functions, callable from a
numba cfunc) give the Jacobian and the inverse dynamics of a packed parameter row
(:func:`stewart_env.dynamics.model.pack_params`): the kernels' own code.
"""

from __future__ import annotations

import ctypes

import numpy as np

from stewart_env import _core

__all__ = [
    "CONSTANT_FORCES",
    "LAW_CTYPES",
    "PD_CONTROL_LAW",
    "PD_LAYOUT",
    "ControlLaw",
    "inverse_dynamics",
    "jacobian",
    "law_forces",
    "numba_law_signature",
]

_P = ctypes.POINTER(ctypes.c_double)
#: ctypes type of a control law (see the module docstring).
LAW_CTYPES = ctypes.CFUNCTYPE(None, ctypes.c_double, _P, _P, _P, _P, _P, ctypes.c_int64, _P)
#: ``jacobian(prm, t, R, J)``: the leg Jacobian J (6,6, row-major) of one platform from a packed
#: parameter row prm, position t (3,) and rotation R (3,3); docs/physics.md section 4.4.
jacobian = ctypes.CFUNCTYPE(None, _P, _P, _P, _P)(_core.LAW_JACOBIAN)
#: ``inverse_dynamics(prm, flags, t, R, v, w, acc, W, out)``: the leg forces out (6,), N, that give
#: one platform the accelerations acc = [a; alpha] under the wrench W, {B}; docs/physics.md
#: section 5.5.
inverse_dynamics = ctypes.CFUNCTYPE(None, _P, ctypes.c_int64, _P, _P, _P, _P, _P, _P, _P)(_core.LAW_INVERSE_DYNAMICS)
#: The parameter row of :data:`PD_CONTROL_LAW`, in order: (name, size).  kp, kd: gains [x, y, z,
#: roll, pitch, yaw]; position, rotation (row-major 3x3), velocity, angular_velocity: the
#: reference in {B} (m, -, m/s, rad/s); gravity_compensation: 1.0 adds the holding forces, 0.0
#: not; gravity_flags: the kernel switch bits of the model giving them; platform: the
#: controller's packed platform row, whose geometry gives J.
PD_LAYOUT = _core.PD_LAYOUT


def numba_law_signature():
    """The numba signature of a control law, for ``numba.cfunc(numba_law_signature())``; needs
    numba (the optional extra ``laws``)."""
    from numba import types

    ptr = types.CPointer(types.float64)
    return types.void(types.float64, ptr, ptr, ptr, ptr, ptr, types.int64, ptr)


class ControlLaw:
    """A compiled control law for :func:`stewart_env.rollout` (contract: the module docstring).

    Args:
        function: a numba ``cfunc`` compiled for :func:`numba_law_signature`, or a ctypes function
            pointer whose argtypes and restype are those of :data:`LAW_CTYPES`.
        n_params: the length of the parameter row the law reads, or None when it reads any
            length (it gets ``n_params`` as an argument); ``rollout`` then refuses other rows.
        name: the law's name in error messages (default: the function's own name).

    Raises:
        ValueError: naming ``control_law``, when ``function`` is none of these.
    """

    __slots__ = ("address", "n_params", "name", "_function")

    def __init__(self, function, n_params: int | None = None, name: str | None = None):
        prototype = getattr(function, "ctypes", function)  # a numba cfunc carries its ctypes face
        if not isinstance(prototype, ctypes._CFuncPtr):
            raise ValueError(
                "control_law: expected a compiled control law (stewart_env.ControlLaw, a numba cfunc or "
                "a ctypes function of type stewart_env.dynamics.rk4.LAW_CTYPES) law(time, position, "
                "rotation, velocity, angular_velocity, params, n_params, forces), got "
                f"{type(function).__name__}"
            )
        name = name or getattr(function, "__name__", None) or getattr(prototype, "__name__", "control_law")
        if prototype.restype is not None or list(prototype.argtypes or ()) != list(LAW_CTYPES._argtypes_):
            raise ValueError(
                f"control_law: {name} does not have the signature of a control law, void law(double time, "
                "double *position, double *rotation, double *velocity, double *angular_velocity, "
                "double *params, int64_t n_params, double *forces)"
            )
        if n_params is not None and (
            isinstance(n_params, bool) or not isinstance(n_params, (int, np.integer)) or n_params < 0
        ):
            raise ValueError(f"n_params: expected a non-negative integer or None, got {n_params!r}")
        self.address = ctypes.cast(prototype, ctypes.c_void_p).value
        self.n_params = None if n_params is None else int(n_params)
        self.name = name
        self._function = function  # keeps the compiled code alive

    @classmethod
    def _compiled(cls, address: int, n_params: int | None, name: str) -> ControlLaw:
        """A law compiled into the package's extension, at ``address``."""
        law = object.__new__(cls)
        law.address, law.n_params, law.name, law._function = address, n_params, name, None
        return law

    def __repr__(self) -> str:
        return f"ControlLaw({self.name!r}, n_params={self.n_params})"


#: The simplest control law, the first six parameters as the forces in N whatever the time and
#: state (the hold of a rollout without a law, for one that records its trajectory).
CONSTANT_FORCES = ControlLaw._compiled(_core.CONSTANT_FORCES, 6, "constant_forces")
#: The task-space PD law F = J^-T (Kp e + Kd edot) [+ holding forces] (He et al. 2018, eq. 56);
#: its parameter row follows :data:`PD_LAYOUT`.
PD_CONTROL_LAW = ControlLaw._compiled(_core.PD_CONTROL_LAW, sum(size for _, size in PD_LAYOUT), "pd_control_law")


def as_control_law(law) -> ControlLaw:
    """``law`` as a :class:`ControlLaw` (itself, or a cfunc or ctypes function wrapped).

    Args:
        law: a :class:`ControlLaw`, a numba cfunc or a ctypes function of the law's signature.

    Raises:
        ValueError: ``law`` is none of these (the message names ``control_law``).
    """
    return law if isinstance(law, ControlLaw) else ControlLaw(law)


def check_law_params(law: ControlLaw, params: np.ndarray) -> None:
    """Raise ValueError naming ``control_law`` when the rows of ``params`` are not as long as the law reads.

    Args:
        law: the control law.
        params: its parameter rows, (n, P).

    Raises:
        ValueError: P is not the law's ``n_params``.
    """
    if law.n_params is not None and params.shape[-1] != law.n_params:
        raise ValueError(
            f"control_law: {law.name} failed on control_params of shape {params.shape}: it reads "
            f"rows of {law.n_params} numbers"
        )


def law_forces(law, params, position, rotation, velocity, angular_velocity, time: float = 0.0) -> np.ndarray:
    """The leg forces (N, 6), N, a control law gives at N states, outside a rollout (a policy's).

    Args:
        law: a :class:`ControlLaw` (or what it accepts).
        params: the law's parameter rows, (N, P) or (1, P) for one row shared by every state.
        position: the platform's position t (N, 3), m, {B}; like the three below a C-contiguous
            float64 array, checked by the caller (e.g. with ``batch_args``).
        rotation: the rotation matrix R (N, 3, 3) of {P} in {B}.
        velocity: the platform's velocity (N, 3), m/s, {B}.
        angular_velocity: the platform's angular velocity omega (N, 3), rad/s, {B}.
        time: the time the law is evaluated at, s.

    Returns:
        (N, 6) leg forces; a force the law leaves unwritten is NaN.
    """
    law = as_control_law(law)
    params = np.ascontiguousarray(params, dtype=np.float64)
    check_law_params(law, params)
    out = np.empty((position.shape[0], 6))
    _core.law_forces_batch(law.address, float(time), position, rotation, velocity, angular_velocity, params, out)
    return out
