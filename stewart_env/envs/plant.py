"""The plant: what simulates the rows of a batch, chosen once from the configuration.

The batch asks four things of its plant (:class:`Plant`): step the rows' state in place over a
control step with the leg forces and the external wrench held, take new parameters for some rows
(domain randomisation at a reset), say how far its closed loops come apart (``closure_error``;
None when they cannot), and give its part of the batch's compiled step (``step_record``; None
when it has none, and the batch then steps it with ``step_inplace``).  Two plants answer:

* :class:`ClosedFormPlant` (``plant="closed_form"``, the default): the closed-form Newton-Euler
  model ``model`` integrated with RK4 (:func:`stewart_env.integrate.rollout_inplace`);
* :class:`stewart_env.mujoco.MujocoPlant` (``plant="mujoco"``, or ``model="mujoco"``): MuJoCo
  simulating the same mechanism, its loops closed by soft constraints.

Either way the batch's dynamics model (``env.unwrapped.model``) is the closed-form ``model`` of
the episode's parameters: the leg sensors, the actuators' holding forces and
``holding_action`` use it, and the closed-form plant integrates it.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol, runtime_checkable

import numpy as np

from stewart_env import _core
from stewart_env.dynamics import Dynamics
from stewart_env.envs.config import CLOSED_FORM, MUJOCO, PhysicsConfig
from stewart_env.integrate import rollout_inplace

__all__ = ["ClosedFormPlant", "Plant", "make_plant"]


@runtime_checkable
class Plant(Protocol):
    """What simulates N platforms for a :class:`~stewart_env.envs.core.PlatformBatch`.

    ``name``: the value of the ``plant`` argument that chose it.  ``closure_error``: (N,) m, the
    largest loop-closure gap of each row after the last step, or None for a plant whose loops
    are closed exactly.
    """

    name: str
    closure_error: np.ndarray | None

    def step_inplace(
        self,
        position: np.ndarray,
        rotation: np.ndarray,
        velocity: np.ndarray,
        angular_velocity: np.ndarray,
        leg_forces: np.ndarray,
        external_wrench: np.ndarray,
        dt: float,
        steps: int,
    ) -> None:
        """Advance every row ``steps`` steps of ``dt`` s, leg forces and external wrench held,
        overwriting the state arrays in place.  No checks: the per-step path.  A row that stops
        being finite comes back non-finite.

        Args:
            position: (N,3) m, the position of P's origin in {B}.
            rotation: (N,3,3) rotation matrices, columns = {P} axes.
            velocity: (N,3) m/s, the velocity of P's origin in {B}.
            angular_velocity: (N,3) rad/s, the platform's angular velocity in {B}.
            leg_forces: (N,6) N, the legs' actuator forces.
            external_wrench: (N,6) [F_ext at P, N; M_ext, N m] in {B}.
            dt: the step, s.
            steps: the number of steps.
        """

    def set_model(self, model: Dynamics, rows: Sequence[int]) -> None:
        """The batch's dynamics model is now ``model`` (one parameter row per platform), whose
        rows ``rows`` hold new parameters (e.g. randomised at a reset).

        Args:
            model: the batch's dynamics model.
            rows: the rows whose parameters are new.
        """

    def step_record(self, physics_dt: float, substeps: int) -> _core.PlantRecord | None:
        """This plant's part of the batch's compiled step (docs/layout.md, "The compiled step's
        contract"), integrating ``substeps`` steps of ``physics_dt`` s per control step and kept up
        to date by :meth:`set_model`; or None for a plant the compiled step cannot run.

        Args:
            physics_dt: the integrator's step, s.
            substeps: the integrator's steps per control step.
        """


class ClosedFormPlant:
    """The closed-form model of the batch (``n`` rows) integrated with RK4, the forces held over each call."""

    name = CLOSED_FORM
    #: The loops of the closed-form models are closed exactly.
    closure_error = None

    def __init__(self, model: Dynamics, n: int = 1):
        self.model = model
        self.n = n  # the rows it simulates
        # the part of the batch's compiled step made last (step_record), which set_model updates
        self._record: _core.PlantRecord | None = None

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        state["_record"] = None  # the batch's copy makes its step, and so this record, again
        return state

    def step_inplace(
        self, position, rotation, velocity, angular_velocity, leg_forces, external_wrench, dt: float, steps: int
    ) -> None:
        """Integrate with RK4 (see :meth:`Plant.step_inplace`).

        Args:
            position: (N,3) m, the position of P's origin in {B}.
            rotation: (N,3,3) rotation matrices, columns = {P} axes.
            velocity: (N,3) m/s, the velocity of P's origin in {B}.
            angular_velocity: (N,3) rad/s, the platform's angular velocity in {B}.
            leg_forces: (N,6) N, the legs' actuator forces.
            external_wrench: (N,6) [F_ext at P, N; M_ext, N m] in {B}.
            dt: the step, s.
            steps: the number of steps.
        """
        rollout_inplace(
            self.model, position, rotation, velocity, angular_velocity, leg_forces, external_wrench, dt, steps
        )

    def set_model(self, model: Dynamics, rows: Sequence[int]) -> None:
        """Take the batch's new model and update the compiled step's record of it (see :meth:`Plant.set_model`).

        Args:
            model: the batch's dynamics model.
            rows: the rows whose parameters are new (the whole packed array is taken).
        """
        self.model = model
        if self._record is not None:
            self._record.set_model(model.packed, model.flags)

    def step_record(self, physics_dt: float, substeps: int) -> _core.PlantRecord:
        """The closed-form plant's part of the compiled step: the model's packed parameters and
        flags, the RK4 substeps.

        Args:
            physics_dt: the integrator's step, s.
            substeps: the RK4 steps per control step.

        Returns:
            Its ``_core.PlantRecord``, made on the first call (and again for other ``physics_dt``
            or ``substeps``) and kept up to date by :meth:`set_model`, so every step made of it
            sees the parameters of each reset.
        """
        record = self._record
        if record is None or (record.physics_dt, record.substeps) != (physics_dt, substeps):
            model = self.model
            self._record = record = _core.PlantRecord(self.n, model.packed, model.flags, physics_dt, substeps)
        return record


def make_plant(physics: PhysicsConfig, model: Dynamics, n: int, actuator: str = "ideal") -> Plant:
    """The plant that ``physics.plant`` names, for n rows of the batch's dynamics model ``model``.

    Args:
        physics: the environment's physics configuration (its ``plant``, ``platform`` and ``physics_dt``).
        model: the batch's dynamics model.
        n: the number of rows.
        actuator: ``"ideal"`` (leg forces) or ``"electric"`` (the MuJoCo plant's electric drives,
            commanded by current set points: ``MujocoPlant(..., actuator="electric")``).

    Raises:
        ImportError: the MuJoCo plant without MuJoCo installed, naming the argument.
    """
    if physics.plant == MUJOCO:
        from stewart_env.mujoco import MujocoPlant  # imports without MuJoCo; the plant names the extra

        try:
            return MujocoPlant([physics.platform] * n, timestep=physics.physics_dt, actuator=actuator)
        except ImportError as error:
            raise ImportError(f"plant={MUJOCO!r} (or model={MUJOCO!r}): {error}") from error
    return ClosedFormPlant(model, n)
