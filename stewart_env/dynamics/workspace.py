"""A model's data: preallocated arrays for a batch of platforms and the calls that use them.

:class:`~stewart_env.dynamics.model.Dynamics` is the model: name, switches and packed parameters,
immutable.  A :class:`Workspace` is its data for a fixed batch size ``n``, as in Pinocchio's
model/data split: every array a call reads or writes is allocated once, C-contiguous float64,
and :meth:`Workspace.forward`, :meth:`~Workspace.inverse`, :meth:`~Workspace.mass_and_bias` and
:meth:`~Workspace.step` hand those arrays straight to the compiled kernels.  A controller loop
writes the state into the arrays in place and calls; nothing is broadcast or re-checked per
call, and no Python object is allocated (the compiled kernels keep a row's 6x6 scratch on the
stack).

What the workspace checks once, when it is made: that the model is a Dynamics and ``n`` a
positive integer matching its parameter rows (1 or ``n``); the arrays' shapes, dtype and
layout then hold by construction (they are read-only attributes, so they cannot be rebound).

What the calls do not check, and the caller promises instead: that the numbers written into the
arrays are finite and that every ``rotation[b]`` is a rotation (orthonormal, det +1, within
:data:`~stewart_env.dynamics.model.ROTATION_TOLERANCE`).  :meth:`Workspace.set_state` copies a
state in with the checks of every other entry point, and :meth:`Workspace.check` runs them on
what the arrays hold now.  Numbers that break the promise give wrong or NaN results, never a
crash.

The results equal those of ``model.forward`` / ``inverse`` / ``mass_and_bias`` and
:func:`stewart_env.rollout` bit for bit: the same kernels run on the same numbers.
"""

from __future__ import annotations

import numpy as np

from stewart_env import _core
from stewart_env.dynamics.model import Dynamics, batch_args, check_step
from stewart_env.rotations import rpy_to_matrix

__all__ = ["Workspace"]

_ARRAYS = {
    # name: (tail shape, what it is)
    "position": ((3,), "P's origin in {B}, m"),
    "rotation": ((3, 3), "the platform's orientation R, columns the {P} axes in {B}"),
    "velocity": ((3,), "velocity of P's origin, m/s, {B}"),
    "angular_velocity": ((3,), "angular velocity, rad/s, {B}"),
    "leg_forces": ((6,), "actuator forces F, N, positive extends the leg"),
    "external_wrench": ((6,), "[force at P, N; moment, N m], {B}"),
    "acceleration": ((6,), "[a; alpha]: acceleration of P's origin, m/s^2, and angular acceleration, rad/s^2, {B}"),
    "mass_matrix": ((6, 6), "M, task space at P, {B}"),
    "bias": ((6,), "h: velocity products, gravity, friction, minus the external wrench; N, N m, {B}"),
}


class Workspace:
    """Preallocated arrays for ``n`` platforms of ``model`` (see the module docstring).

    Arrays (read-only attributes; write their contents, e.g. ``ws.position[0] = t``), each with
    the batch size ``n`` first: ``position`` (n,3), ``rotation`` (n,3,3), ``velocity`` (n,3),
    ``angular_velocity`` (n,3) the state; ``leg_forces`` (n,6), ``external_wrench`` (n,6);
    ``acceleration`` (n,6) [a; alpha]; ``mass_matrix`` (n,6,6) and ``bias`` (n,6).  They start
    at the home pose of the model's first parameter row, at rest, with zero forces and wrench.

    Calls (no checks, no Python allocation; each returns the arrays it wrote, overwritten by the next):

    * :meth:`forward`: state, leg_forces, external_wrench -> acceleration (docs/physics.md section 5.4);
    * :meth:`inverse`: state, acceleration, external_wrench -> leg_forces (section 5.5);
    * :meth:`mass_and_bias`: state, external_wrench -> mass_matrix, bias (section 5.4);
    * :meth:`step`: RK4 steps with leg_forces and external_wrench held; overwrites the state (section 5.6).

    Args:
        model: the :class:`Dynamics` whose parameter rows the workspace uses.
        n: the batch size (the model's number of parameter rows, or any if it has one).

    Raises:
        ValueError: ``model`` not a Dynamics, or ``n`` not a positive integer that fits the model.

    Examples:
        >>> import numpy as np, stewart_env as se
        >>> model = se.make_dynamics("improved", se.load_platform("dasgupta1998"))
        >>> ws = model.workspace()
        >>> ws.acceleration[0] = 0.0           # at rest at home: the holding forces
        >>> print(np.round(ws.inverse()[0], 1))
        [193.9 145.4 153.1 172.3 159.6 188.9]
        >>> ws.leg_forces[0] += 10.0           # 10 N more on every leg: the platform rises
        >>> bool(ws.forward()[0, 2] > 0)
        True
    """

    __slots__ = ("_model", "_n", "_packed", "_flags", "_bound", *(f"_{name}" for name in _ARRAYS))

    def __init__(self, model: Dynamics, n: int = 1):
        if not isinstance(model, Dynamics):
            raise ValueError(f"model: expected a Dynamics (stewart_env.make_dynamics), got {type(model).__name__}")
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
            raise ValueError(f"n: expected a positive integer batch size, got {n!r}")
        n = int(n)
        rows = model.packed.shape[0]
        if rows not in (1, n):
            raise ValueError(f"n: the model has {rows} parameter rows, so the workspace needs n = {rows}, got {n}")
        self._model, self._n = model, n
        self._packed, self._flags = model.packed, model.flags
        try:
            for name, (tail, _) in _ARRAYS.items():
                object.__setattr__(self, f"_{name}", np.zeros((n,) + tail))
        except (ValueError, MemoryError):
            size = n * sum(int(np.prod(tail)) for tail, _ in _ARRAYS.values()) * 8
            raise ValueError(
                f"n: a workspace of {n} platforms needs {size / 2**30:.3g} GiB, more than can be allocated"
            ) from None
        # the kernels get the arrays' addresses once, here (the bound object holds the arrays); the
        # arrays are never replaced
        self._bound = _core.BoundWorkspace(
            self._packed,
            self._flags,
            self._position,
            self._rotation,
            self._velocity,
            self._angular_velocity,
            self._leg_forces,
            self._external_wrench,
            self._acceleration,
            self._mass_matrix,
            self._bias,
        )
        home = model.params_of(0)
        self._position[:] = home.home_position
        self._rotation[:] = rpy_to_matrix(home.home_rpy)

    model = property(lambda self: self._model, doc="The Dynamics the workspace was made for.")
    n = property(lambda self: self._n, doc="The batch size.")
    position = property(lambda self: self._position, doc="(n,3) " + _ARRAYS["position"][1])
    rotation = property(lambda self: self._rotation, doc="(n,3,3) " + _ARRAYS["rotation"][1])
    velocity = property(lambda self: self._velocity, doc="(n,3) " + _ARRAYS["velocity"][1])
    angular_velocity = property(lambda self: self._angular_velocity, doc="(n,3) " + _ARRAYS["angular_velocity"][1])
    leg_forces = property(lambda self: self._leg_forces, doc="(n,6) " + _ARRAYS["leg_forces"][1])
    external_wrench = property(lambda self: self._external_wrench, doc="(n,6) " + _ARRAYS["external_wrench"][1])
    acceleration = property(lambda self: self._acceleration, doc="(n,6) " + _ARRAYS["acceleration"][1])
    mass_matrix = property(lambda self: self._mass_matrix, doc="(n,6,6) " + _ARRAYS["mass_matrix"][1])
    bias = property(lambda self: self._bias, doc="(n,6) " + _ARRAYS["bias"][1])

    def __repr__(self) -> str:
        return f"Workspace({self._model!r}, n={self._n})"

    def __reduce__(self):
        # a copy (copy, deepcopy, pickle) is a new workspace, its arrays bound anew, holding these numbers
        return _workspace_holding, (self._model, self._n, {name: getattr(self, f"_{name}") for name in _ARRAYS})

    def set_state(self, position, rotation, velocity, angular_velocity) -> None:
        """Copy a state into the arrays, with the checks of every entry point
        (:func:`~stewart_env.dynamics.model.batch_args`).

        Args:
            position: (3,) m, or (n,3).
            rotation: (3,3), or (n,3,3).
            velocity: (3,) m/s, or (n,3).
            angular_velocity: (3,) rad/s, or (n,3).  One platform's values are broadcast to every row.

        Raises:
            ValueError: a bad argument (the message names it).
        """
        n, _, a = batch_args(
            self._n,
            position=(position, (3,)),
            rotation=(rotation, (3, 3)),
            velocity=(velocity, (3,)),
            angular_velocity=(angular_velocity, (3,)),
        )
        if n != self._n:  # a batch given to a workspace of one platform
            name = next(k for k, x in a.items() if x.shape[0] != self._n)
            raise ValueError(
                f"{name}: expected shape {a[name].shape[1:]} or ({self._n}, ...) for this workspace "
                f"of n = {self._n}, got a batch of {n}"
            )
        self._position[:] = a["position"]
        self._rotation[:] = a["rotation"]
        self._velocity[:] = a["velocity"]
        self._angular_velocity[:] = a["angular_velocity"]

    def check(self) -> None:
        """Run the entry points' checks on what the input arrays hold now.

        Raises:
            ValueError: a number not finite or a rotation that is not one (the message names the array).
        """
        batch_args(
            self._n,
            **{
                name: (getattr(self, f"_{name}"), tail)
                for name, (tail, _) in _ARRAYS.items()
                if name not in ("acceleration", "mass_matrix", "bias")
            },
        )

    def forward(self) -> np.ndarray:
        """Forward dynamics from the state, ``leg_forces`` and ``external_wrench``.

        docs/physics.md section 5.4; paper eq. 49 or 55.

        Returns:
            ``acceleration`` (n,6) [a; alpha], overwritten by the next call.
        """
        self._bound.forward()
        return self._acceleration

    def inverse(self) -> np.ndarray:
        """Inverse dynamics: the leg forces that produce ``acceleration`` in the state, with ``external_wrench``.

        docs/physics.md section 5.5.

        Returns:
            ``leg_forces`` (n,6), overwritten by the next call.
        """
        self._bound.inverse()
        return self._leg_forces

    def mass_and_bias(self) -> tuple[np.ndarray, np.ndarray]:
        """Mass matrix and bias of M [a; alpha] + h = J^T F in the state, ``external_wrench`` moved into h.

        docs/physics.md section 5.4.

        Returns:
            The pair (``mass_matrix`` (n,6,6), ``bias`` (n,6)), overwritten by the next call.
        """
        self._bound.mass_and_bias()
        return self._mass_matrix, self._bias

    def step(self, dt: float, steps: int = 1) -> None:
        """Advance the state by classical RK4 steps, ``leg_forces`` and ``external_wrench`` held.

        Overwrites position, rotation, velocity and angular_velocity.  A row whose state stops being
        finite stays so (see :meth:`check`).  docs/physics.md section 5.6.

        Args:
            dt: the step, s.
            steps: the number of steps.

        Raises:
            ValueError: a bad ``dt`` or ``steps``.
        """
        dt, steps = check_step(dt, steps)
        self._bound.step(dt, steps)


def workspace(self: Dynamics, n: int = 1) -> Workspace:  # noqa: D417  (self: a method of Dynamics, below)
    """Preallocated arrays for ``n`` platforms of this model, and the calls that use them without
    checking or allocating.

    Args:
        n: the batch size.

    Returns:
        The :class:`Workspace`.

    Raises:
        ValueError: ``n`` not a positive integer that fits the model's parameter rows.
    """
    return Workspace(self, n)


# The model makes its data: Dynamics.workspace is defined here, beside the Workspace it makes, so
# that imports run one way, model <- workspace (the package's __init__ imports both, so every
# Dynamics has the method).
workspace.__qualname__ = "Dynamics.workspace"
Dynamics.workspace = workspace


def _workspace_holding(model: Dynamics, n: int, arrays: dict) -> Workspace:
    """A workspace of ``model`` for ``n`` platforms whose arrays hold ``arrays`` (name -> array):
    how a copied or unpickled workspace is made."""
    ws = Workspace(model, n)
    for name, value in arrays.items():
        getattr(ws, f"_{name}")[...] = value
    return ws
