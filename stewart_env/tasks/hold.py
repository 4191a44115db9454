"""Hold: keep the platform still at home while it carries a payload of unknown mass and place."""

from __future__ import annotations

import numpy as np

from stewart_env.params import PlatformParams
from stewart_env.rotations import rpy_to_matrix
from stewart_env.state import PlatformState
from stewart_env.tasks.base import StepView, Task, option
from stewart_env.validation import real

#: Bound of the payload option, in platform masses: beyond it no platform's actuators hold it.
MAX_PAYLOAD = 10.0


class HoldTask(Task):
    """Hold the home pose, starting there at rest, under a payload drawn per episode.

    The payload is a dead weight on the platform: a point mass m, uniform in [0, max_payload],
    at a point c of {P} uniform in the disc of radius payload_radius about P's origin in the {P}
    x-y plane.  It loads the platform with its weight alone (its inertia is not modelled): the
    force m g at the point R c, the wrench [m g; (R c) x m g] in {B}, evaluated at the state each
    control step starts from and held over the step.  The payload is not observed.

    The options are the environment's ``task_options``.  Below, m_p is the platform's mass and r
    the mean distance of the platform joints from P's origin in the {P} x-y plane (dasgupta1998:
    40 kg, 0.62 m).

    Args:
        params: the platform's nominal parameters.
        control_dt: the control step, s.
        max_payload: kg, 0 to 10 m_p, default 0.5 m_p.
        payload_radius: m, 0 to r, default r / 2.
        **weights: the reward weights and scales of :class:`~stewart_env.tasks.RewardWeights`.

    Raises:
        ValueError: an unknown option or one out of its range (the message names it).
    """

    name = "hold"

    def __init__(self, params: PlatformParams, control_dt: float, *, max_payload=None, payload_radius=None, **weights):
        mass = params.platform.mass
        radius = float(np.mean(np.linalg.norm(params.platform_joints[:, :2], axis=1)))
        self.max_payload = (
            0.5 * mass if max_payload is None else real(option("max_payload"), max_payload, 0.0, MAX_PAYLOAD * mass)
        )
        self.payload_radius = (
            0.5 * radius if payload_radius is None else real(option("payload_radius"), payload_radius, 0.0, radius)
        )
        self._home_rotation = rpy_to_matrix(params.home_rpy)
        super().__init__(params, control_dt, **weights)

    def episode_fields(self):
        """The episode arrays (see :meth:`Task.episode_fields`): the target pose, the payload's mass and its offset from P's origin in {P}."""
        return {"target_position": (3,), "target_rotation": (3, 3), "payload_mass": (), "payload_offset": (3,)}

    def initialize_episode(self, rng):
        """Draw one row's episode (see :meth:`Task.initialize_episode`): the start and target at home, a payload mass and an offset uniform over the disc.

        Args:
            rng: the row's generator.
        """
        mass = rng.uniform(0.0, self.max_payload)
        # sqrt of a uniform radius fraction: uniform over the disc's area
        r = self.payload_radius * np.sqrt(rng.uniform())
        angle = rng.uniform(0.0, 2.0 * np.pi)
        p = self.params
        start = PlatformState(p.home_position.copy(), self._home_rotation.copy(), np.zeros(3), np.zeros(3))
        return start, {
            "target_position": p.home_position,
            "target_rotation": self._home_rotation,
            "payload_mass": mass,
            "payload_offset": np.array([r * np.cos(angle), r * np.sin(angle), 0.0]),
        }

    def external_wrench(self, view: StepView, dt, out) -> None:
        """Write the wrench held over the step (see :meth:`Task.external_wrench`): the payload's weight m g at P and its moment (R c) x m g.

        Args:
            view: the batch's :class:`StepView` at the step's start.
            dt: the step's length, s.
            out: (N,6) the wrench [F_ext at P, N; M_ext, N m] in {B}, written into.
        """
        force = view.episode["payload_mass"][:, None] * self.params.gravity
        arm = np.einsum("nij,nj->ni", view.state.rotation, view.episode["payload_offset"])
        out[:, :3] = force
        # (R c) x m g written out: the same products as np.cross, at a third of its cost per step.
        (ax, ay, az), (fx, fy, fz) = arm.T, force.T
        out[:, 3] = ay * fz - az * fy
        out[:, 4] = az * fx - ax * fz
        out[:, 5] = ax * fy - ay * fx
