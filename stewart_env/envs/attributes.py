"""What both environments show of their batch: the attributes of ``env.unwrapped``, and drawing."""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium.error import ResetNeeded

from stewart_env.dynamics import Dynamics
from stewart_env.envs.core import PlatformBatch
from stewart_env.envs.plant import Plant
from stewart_env.params import PlatformParams
from stewart_env.state import PlatformState, Reference

__all__ = ["BatchAttributes"]


class BatchAttributes:
    """What both environments show of their :class:`PlatformBatch`.

    ``_rows`` picks row 0 (the single environment: arrays without the batch axis) or every row
    (the vector environment: a leading N).  Arrays are copies.
    """

    _core: PlatformBatch
    _rows: int | slice
    _renderer = None  # made on first render
    _reset_done = False  # set by the first reset()

    def set_step_mode(self, mode: str) -> None:
        """Choose how every following step is made, the same numbers either way (the environment
        page, "The step"): "auto" (the default), "fused" or "parts".

        Args:
            mode: as ``stewart_env.envs.core.PlatformBatch.set_step_mode`` takes it.

        Raises:
            ValueError: an unknown ``mode``, or "fused" where the fused step cannot run.
        """
        self._core.set_step_mode(mode)

    def _rows_of(self, array: np.ndarray) -> np.ndarray:
        return array[self._rows].copy()

    def __getstate__(self) -> dict[str, Any]:
        # A copy draws with a renderer of its own, made on its first render().
        state = self.__dict__.copy()
        state.pop("_renderer", None)
        return state

    def _check_reset(self) -> None:
        """Refuse a step before the first reset(), which draws the episode (the state would be zeros)."""
        if not self._reset_done:
            raise ResetNeeded(
                f"{type(self).__name__}: call reset() before step(); the first reset() draws the episode's start state"
            )

    @property
    def observation_layout(self) -> dict[str, slice]:
        """Observation term name -> slice of a (row's) observation vector."""
        return dict(self._core.observation_layout)

    def decode_observation(self, observation) -> dict[str, np.ndarray]:
        """An observation, or a batch of them, in physical units by term name (undoes the scaling).

        Args:
            observation: an observation vector, or a batch of them (N, obs_dim).
        """
        return self._core.decode_observation(observation)

    @property
    def state(self) -> PlatformState:
        """The platform's current state, {B}: position, rotation, velocity, angular velocity."""
        return PlatformState(*(self._rows_of(x) for x in self._core._state))

    @property
    def target(self) -> Reference:
        """The task's current reference: position, rotation, velocity, angular velocity, {B}."""
        return Reference(*(self._rows_of(x) for x in self._core.reference))

    @property
    def model(self) -> Dynamics:
        """The closed-form dynamics model of the current episode (one parameter set, or one per
        row with domain randomisation): what the task's holding forces, the leg sensors and
        :func:`~stewart_env.envs.holding_action` use, and what the closed-form plant integrates.
        On ``plant="mujoco"`` MuJoCo simulates the rows and this is the closed-form ``model`` of
        the same parameters (see :attr:`plant`)."""
        return self._core.model

    @property
    def plant(self) -> Plant:
        """What simulates the platform (:class:`~stewart_env.envs.plant.Plant`): ``plant.name`` is
        ``"closed_form"`` (``model`` integrated with RK4) or ``"mujoco"``."""
        return self._core.plant

    @property
    def platform(self) -> PlatformParams:
        """The nominal PlatformParams."""
        return self._core.platform

    @property
    def termination_reasons(self) -> tuple[str, ...]:
        """The names of the termination codes of ``info["termination"]``: "" (code 0, the episode
        goes on), then the environment's reasons by priority, then the task's."""
        return self._core.termination_reasons

    @property
    def episode_params(self):
        """The PlatformParams of the current episode (with domain randomisation, the nominal ones
        scaled by the episode's factors; else the nominal ones); a tuple of one per row in the
        vector environment."""
        core = self._core
        if isinstance(self._rows, slice):
            return tuple(core.episode_params(i) for i in range(core.n))
        return core.episode_params(self._rows)

    @property
    def task(self):
        """The task object (see stewart_env.tasks)."""
        return self._core.task

    @property
    def leg_forces(self) -> np.ndarray:
        """The leg forces (6,) N applied over the last control step (after clipping and lag)."""
        return self._rows_of(self._core.leg_forces)

    @property
    def external_wrench(self) -> np.ndarray:
        """The external wrench (6,) [N; N m] in {B} applied over the last control step."""
        return self._rows_of(self._core.external_wrench)

    @property
    def leg_lengths(self) -> np.ndarray:
        """Leg lengths (6,) m now."""
        return self._rows_of(self._core.leg_lengths)

    @property
    def dt(self) -> float:
        """The control period, s."""
        return self._core.control_dt

    def _scene(self) -> tuple[np.ndarray, ...]:
        """What a frame shows of every row: position, rotation, leg forces, target position and
        rotation, time (the batch's own arrays, not copies)."""
        core = self._core
        ref = core.reference
        return core.position, core.rotation, core.leg_forces, ref.position, ref.rotation, core.time

    def _draw(self, row: int = 0, label: str = "", scene: tuple[np.ndarray, ...] | None = None):
        """Row ``row`` of ``scene`` (default: now, see :meth:`_scene`) drawn by a PlatformRenderer
        made on first use (the target pose as a ghost): an RGB frame, or None in human mode."""
        core = self._core
        if self._renderer is None:
            from stewart_env.envs.render import PlatformRenderer  # matplotlib only when rendering

            p = core.platform
            size = core.config.render
            self._renderer = PlatformRenderer(
                p.base_joints,
                p.platform_joints,
                p.home_position,
                p.limits.leg_force,
                size.width,
                size.height,
                self.render_mode,
            )
        position, rotation, forces, target_position, target_rotation, time = scene or self._scene()
        return self._renderer.render(
            position[row],
            rotation[row],
            forces[row],
            target_position=target_position[row],
            target_rotation=target_rotation[row],
            text=f"{label}t = {time[row]:.2f} s",
        )

    def _close_renderer(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
