"""The single Stewart platform environment, ``StewartPlatform-v1`` (and its earlier version ``-v0``)."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from stewart_env.dynamics.model import check_rotation
from stewart_env.envs.attributes import BatchAttributes
from stewart_env.envs.config import RENDER_MODES, EnvConfig
from stewart_env.envs.core import PlatformBatch
from stewart_env.envs.infos import row_info
from stewart_env.envs.keywords import check_arguments, with_signature
from stewart_env.rotations import rpy_to_matrix
from stewart_env.state import PlatformState
from stewart_env.validation import check_action, real_array, reset_options

__all__ = ["StewartPlatformEnv", "holding_action"]

_ROW0 = np.zeros(1, dtype=np.int64)
#: The action dtypes the compiled step reads as they are.
_FLOATS = (np.dtype(np.float32), np.dtype(np.float64))


def holding_action(env, position=None, rotation=None) -> np.ndarray:
    """The action whose leg forces hold the env's platform at rest at a pose in {B}.

    The env's model at zero rates and accelerations gives the forces; the inverse of the
    action's affine map to the force range gives the action (not clipped).

    Args:
        env: a StewartPlatform environment (wrapped or not).
        position: (3,) position of P's origin, m; default the platform's home position.
        rotation: (3,3) rotation of {P}; default the platform's home orientation.

    Returns:
        The action (6,).

    Examples:
        >>> import gymnasium as gym, numpy as np
        >>> from stewart_env.envs import holding_action
        >>> env = gym.make("StewartPlatform-v1", task="hold", task_options={"max_payload": 0.0})
        >>> _ = env.reset(seed=0)
        >>> for _ in range(10):
        ...     observation, reward, terminated, truncated, info = env.step(holding_action(env))
        >>> print(np.round(env.unwrapped.state.position, 6) + 0.0)
        [0.  0.  0.4]
    """
    u = env.unwrapped
    p = u.platform
    position = p.home_position if position is None else position
    rotation = rpy_to_matrix(p.home_rpy) if rotation is None else rotation
    z = np.zeros(3)
    forces = u.model.inverse(position, rotation, z, z, z, z)
    lo, hi = p.limits.leg_force
    return (forces - 0.5 * (lo + hi)) / (0.5 * (hi - lo))


class StewartPlatformEnv(BatchAttributes, gym.Env):
    """## Description

    A 6-UPS Stewart platform: a rigid platform carried by six extensible legs, each a lower leg
    (cylinder) hung on a universal joint at the base and an upper leg (piston) that slides in it and
    meets the platform in a spherical joint.  The agent commands the six actuator forces along the
    legs; the platform moves under them, gravity, viscous joint friction and, in the disturbance and
    hold tasks, an external wrench.  The dynamics are closed-form Newton-Euler models of the whole mechanism
    (platform and twelve leg bodies), chosen by name: `"improved"` (He et al. 2018, exact rigid-body
    dynamics), `"improved_centroidal"` (the same in its centroidal form) and `"classical"`
    (Dasgupta and Mruthyunjaya 1998 as He et al. describe it), or an ablation such as
    `"improved+c1"`.  They are integrated with RK4 at `physics_dt` while the forces are held over
    each control step of `control_dt`: the `"closed_form"` plant.  `plant="mujoco"` (the `mujoco`
    extra; also spelled `model="mujoco"`, which keeps the `"improved"` model) runs the same tasks,
    observations and rewards on MuJoCo's simulation of the same mechanism (`stewart_env.mujoco`:
    the loops closed by soft equality constraints, RK4 at `physics_dt`); the step's `info` then also
    holds `closure_error`, the largest loop-closure gap in m.  On either plant `model` gives the
    leg sensors, the actuators' holding forces and `env.unwrapped.model`; `env.unwrapped.plant.name`
    says which plant runs.

    The default platform, `"dasgupta1998"`, is the published Dasgupta/Tsai test manipulator: a 40 kg
    platform, legs of 1.26 m at home, stroke 1.0-1.6 m, forces within +-2000 N.  Five tasks:
    `"setpoint"` (reach a pose and hold it), `"tracking"` (follow a six-axis sinusoidal reference),
    `"disturbance"` (hold home against a random external wrench), `"hold"` (hold home under a
    random payload) and `"cueing"` (move so that a person on the platform perceives a vehicle's
    motion).  The task owns its observation terms, its reward terms and their weights, and
    its termination; the environment adds nothing to them.

    Frames and units: {B} is the base frame (z up, gravity -z), {P} the platform frame with origin P;
    R is the rotation of {P} in {B} (columns = {P} axes); positions in m, angles in rad, velocities of
    P in m/s and angular velocities in {B} in rad/s, forces in N, moments in N m.

    ## Action Space

    `Box(-1.0, 1.0, (6,), float32)`: one number per leg, mapped affinely onto the platform's
    actuator force range `limits.leg_force = (F_min, F_max)`:

        F_i = (F_max + F_min) / 2 + a_i (F_max - F_min) / 2        (dasgupta1998: F_i = 2000 a_i N)

    A positive force extends the leg.  Values outside [-1, 1] are clipped.  An action must be real
    numbers (integers or floats of any width) of shape (6,), all finite: NaN or inf, another shape,
    or bools, complex numbers, strings, dates or objects raise a `ValueError` naming `action` and
    saying what is wrong (a wrong kind is also a `TypeError`).  A torch tensor is read detached
    (one that requires grad included: no gradient flows through the simulation); a numpy masked
    array with masked entries is refused (fill them first, e.g. `action.filled(0.0)`), one without
    is read as its data.  The vector environment checks its (N, 6) actions the same way.  The forces are held
    constant over the control step (zero-order hold) while the physics takes
    `control_dt / physics_dt` RK4 substeps.  With `actuator_tau > 0` the applied forces follow the
    commanded ones through a first-order lag, discretised exactly per control step:
    `F += (1 - exp(-control_dt / actuator_tau)) (F_cmd - F)`, the updated F being held over the step.
    Note that a = 0 is zero force: the platform falls unless the policy holds it (about 130-225 N per
    leg, a ~ 0.1, for dasgupta1998).

    **Action modes** (`action_mode`), **pose laws** (`pose_law`) and **actuators** (`actuator`).
    The action is always `Box(-1.0, 1.0, (6,), float32)`, refused and clipped as above; what it
    commands depends on `action_mode`:

    | `action_mode` | a_i commands | mapping | unit |
    |---|---|---|---|
    | `"force"` (default) | leg i's force set point | F_i = (F_max + F_min) / 2 + a_i (F_max - F_min) / 2 over `limits.leg_force` | N |
    | `"leg_length"` | leg i's length set point | l_i = (l_max + l_min) / 2 + a_i (l_max - l_min) / 2 over `limits.leg_length` | m |
    | `"pose"` | [x, y, z, roll, pitch, yaw] of P | p = c + a h over the workspace box (c, h as in Observation Space); angle = home_rpy + a A (`limits.max_angle`) | m, rad |

    In the leg_length and pose modes an inner loop runs at the physics rate, inside the compiled
    step (every `physics_dt`, the action held over the control step, as on a machine whose policy
    runs slower than its servo), on the nominal model `model`:

    | `pose_law` | the leg-force set points f (N) at each physics step |
    |---|---|
    | (leg_length mode) and `"ik"` | leg servo per leg, f_i = K_p (l_ref,i - l_i) - K_d l_dot_i + the forces holding at rest the commanded pose (ik) or the pose at the control step's start (leg_length); in pose mode l_ref by the inverse kinematics of the pose set point |
    | `"pd_gravity"` | task-space PD with gravity compensation, f = J^-T (K_p e + K_d e_dot) + holding forces (paper eq. 56; e the pose error, rpy angles) |
    | `"computed_torque"` | f = inverse dynamics at the acceleration K_p e - K_d [v; w] (e: position error and rotation vector of R_ref R^T), the reflected masses included |

    The loops are tuned to a 5 Hz bandwidth with damping ratio 0.7 (`stewart_env.envs.actuation`):
    the leg servo for a leg carrying a sixth of the platform, its upper leg and its reflected mass;
    PD for the platform's mass and inertia; computed torque K_p = omega_n^2 (1/s^2), K_d = 2 zeta
    omega_n (1/s).  f is clipped to `limits.leg_force`.  The actuator turns f into the forces the
    legs feel:

    | `actuator` | model | state (`observe_actuators=True` appends it) |
    |---|---|---|
    | `"ideal"` | a force source, F = f | none |
    | `"lag"` | first-order lag of `actuator_tau` s (in force mode per control step, as above; otherwise per physics step) | none |
    | `"electric"` | servo motor on a ball screw in current control: current set point f / (eta k K_t) A through the current loop, its limit and the voltage envelope, less the screw's friction; the rotor's reflected mass m_r = k^2 J_m kg in the dynamics | motor currents (6, A, / current_limit) |
    | `"hydraulic"` | valve-controlled cylinder (Merritt): a force loop onto the valve, spool command (f - (P_A A_A - P_B A_B)) / (P_s A_A), through the spool, the orifices and the compressible chambers | chamber pressures P_A, P_B of each leg (12, Pa, (P - (P_s + P_r) / 2) / ((P_s - P_r) / 2)) |

    `actuator=None` (default) is `"lag"` when `actuator_tau > 0`, else `"ideal"`: today's force
    mode, unchanged.  The electric and hydraulic actuators read their parameters from the
    platform's `actuators:` section (`motion_simulator` has both; docs/physics.md section 10) and
    refuse a platform without that set.  Their states, the lag's and the inner loops' are stepped
    at the physics rate and held over the RK4 substep; at a reset the actuators start at
    equilibrium with the forces that hold the start state at rest.  These modes need the
    closed-form plant.

    ## Observation Space

    `Box(-inf, inf, (D,), float32)`.  `env.unwrapped.observation_layout` maps each term's name to its
    slice, and `env.unwrapped.decode_observation(obs)` returns every term in physical units.  With
    `normalize_observation=True` (default) each entry is `(value - offset) / scale`, the scales taken
    from the platform's limits so that values inside the limits are of order one: `h` = half the
    workspace box `(position_max - position_min) / 2` (dasgupta1998: 0.25, 0.25, 0.15 m), `c` its
    centre, `A` = `limits.max_angle` (0.5 rad), `s` = half the stroke (0.3 m), `f` = half the force
    range (2000 N).  With `normalize_observation=False` the observation is in SI units.

    Default (`observation_mode="pose"`), setpoint and disturbance tasks, D = 21:

    | index | name | observation | unit | scaling |
    |---|---|---|---|---|
    | 0-2 | position | x, y, z of P in {B} | m | (p - c) / h |
    | 3-5 | orientation | first column of R: the {P} x axis in {B} | - | none |
    | 6-8 | orientation | second column of R: the {P} y axis in {B} | - | none |
    | 9-11 | velocity | velocity of P in {B} | m/s | v / h (h per second) |
    | 12-14 | angular_velocity | angular velocity in {B} | rad/s | w / A |
    | 15-17 | position_error | target position - position, {B} | m | e / h |
    | 18-20 | orientation_error | rotation vector of R_target R^T, {B} | rad | e / A |

    The two columns of R are a continuous description of the orientation (no angle wrapping or
    gimbal lock); the third column is their cross product.  The tracking task appends (D = 45):

    | index | name | observation | unit | scaling |
    |---|---|---|---|---|
    | 21-23 | velocity_error | reference velocity - velocity | m/s | e / h |
    | 24-26 | angular_velocity_error | reference angular velocity - angular velocity | rad/s | e / A |
    | 27-44 | reference_preview | for j = 1, 2, 3: reference position at t + 0.1 j s minus the position (3), rotation vector of R_ref(t + 0.1 j s) R^T (3) | m, rad | / h, / A |

    The cueing task observes no pose error; after the pose block it appends (D = 22 + 6 k):

    | index | name | observation | unit | scaling |
    |---|---|---|---|---|
    | 15-17 | vehicle_specific_force | the vehicle's specific force at the head now, {H} | m/s² | / 9.80665 |
    | 18-20 | vehicle_angular_velocity | the vehicle's angular velocity now, {H} | rad/s | none |
    | 21 to 20 + 6 k | preview | with `task_options={"preview": k}`: for j = 1..k, the vehicle's specific force (3) and angular velocity (3) j control steps ahead | m/s², rad/s | / 9.80665, none |
    | D-1 | motion_time_left | the time to the motion's end | s | / 10 |

    With `observation_mode="sensors"` the pose block (indices 0-14) is replaced by what leg encoders
    measure: `leg_lengths` (6, m, (L - stroke centre) / s) and `leg_rates` (6, m/s, / s); the task
    terms follow unchanged (D = 18 for setpoint).  With `actuator_tau > 0` the applied forces
    `leg_forces` (6, N, (F - force centre) / f) follow the pose or sensor block, since the lagged
    force is part of the state.  `observation_noise` adds Gaussian noise of the given standard
    deviation, in observation units (a number for every entry, or a dict from term name to std);
    `observation_delay=k` returns the observation of k control steps ago (at reset, every slot holds
    the first observation).

    With `error_integral=True` the observation ends with one more term (D = 27 for setpoint):

    | index | name | observation | unit | scaling |
    |---|---|---|---|---|
    | D-6 to D-4 | error_integral | time integral of position_error over the episode | m s | / (T h) |
    | D-3 to D-1 | error_integral | time integral of orientation_error over the episode | rad s | / (T A) |

    It is the state of an integral controller: zero at reset, after each control step it adds the
    step's true (noise-free) errors times `control_dt`, and it is clipped elementwise to
    +-T h and +-T A (anti-windup), T = `error_integral_limit` (default 0.1 s), so that its
    normalised entries lie in [-1, 1].  With `error_integral_band=b` the integration is
    conditional: an error component adds to the integral only while |e| <= b h (position) or b A
    (orientation), so that the approach to the target does not wind it up.  Observation noise and
    delay then apply to it as to any other term.

    ## Rewards

    The task's reward terms, summed; every shipped task but `cueing` uses the tracking-error reward
    of its reference (the cueing task's reward compares what a person perceives in the vehicle
    and on the platform, less its use of the workspace and the stroke: `reward_specific_force`,
    `reward_angular_velocity`, `reward_workspace`, `reward_stroke`, `reward_control`,
    `reward_termination`; the tasks page gives it).  Every step, with the errors e of the observation (reference minus actual; e_o as
    an angle):

        r = position_reward_weight    * exp(-|e_p| / position_reward_scale)
          + orientation_reward_weight * exp(-|e_o| / orientation_reward_scale)
          - velocity_cost_weight      * (1 - exp(-(|e_v| / velocity_cost_scale
                                                   + |e_w| / angular_velocity_cost_scale)))
          - ctrl_cost_weight          * mean(a_i^2)                  (a clipped to [-1, 1])
          - termination_cost          on the step that terminates with a failure

    With the defaults (0.5, 0.05 m, 0.5, 0.1 rad, 0.1, 0.5 m/s, 1 rad/s, 0.1, 10; in v1
    `tracking` and `disturbance` use 0.01 m and 0.02 rad for the two scales, so that the
    millimetre errors their questions are about weigh in the reward) a step earns at most
    1 (on target, at the target velocity, zero force) and at least -10.2.  Each term is in `info`:
    `reward_position`, `reward_orientation`, `reward_velocity`, `reward_control` and
    `reward_termination`; they sum to the reward.  The weights and scales are options of the task,
    in `task_options` (e.g. `task_options={"termination_cost": 50.0}`), weights in [0, 1e6] and
    scales in (0, 1e6]; given as environment arguments they raise a `TypeError` that says so.  A
    task's own termination reason may be a success (`task.success_reasons`), which pays no
    termination cost; the platform's limits are failures.

    ## Starting State

    - `setpoint`: at rest at a start pose; the target pose is fixed for the episode.  By default
      (`randomize=True`) start and target are drawn independently and uniformly, positions in
      home +- `position_range` (default 0.4 h: 0.1, 0.1, 0.06 m) and roll, pitch, yaw in
      home +- `angle_range` (default 0.4 A = 0.2 rad), each redrawn until it lies inside the limits
      with 10 % margins.  `randomize=False` gives the case study of He et al. (2018): start
      (0.1, 0, 0.395) m, target (0.1, 0, 0.4) m, both at rpy (0, 0, -0.2) rad (written as offsets
      from home, so other platforms get the same offsets); `start_position`, `start_rpy`,
      `target_position`, `target_rpy` override them.
    - `tracking`: on the reference at t = 0 (its pose and twist).  Per episode and axis (x, y, z,
      roll, pitch, yaw) an amplitude uniform in [0, max] (max 0.4 h and 0.4 A by default), a
      frequency uniform in `frequency_range` (0.1-0.5 Hz) and a uniform phase; the reference is home
      plus the six sinusoids, its amplitudes scaled down until every corner of its range lies inside
      the limits with 10 % margins.
    - `cueing`: at rest at home.  Per episode a vehicle motion: a name drawn uniformly from
      `motions` and a seed (below 2**30 in training, a held-out evaluation seed with
      `split="evaluation"`); the episode lasts the motion's duration.
    - `disturbance`: at rest at home, the target.  Per episode: sinusoidal forces and moments on each
      axis (amplitudes up to 0.2 W and 0.2 W r, W the platform's weight, r its joint radius;
      0.2-2 Hz) plus `n_impulses` = 2 pulses of 0.05 s at random times in the first 5 s (force up to
      W, moment up to 0.5 W r, random directions), applied as the external wrench on the platform.
      The wrench is not observed.
    - `hold`: at rest at home, the target.  Per episode a payload of mass uniform in
      [0, `max_payload`] (default half the platform's mass, 20 kg) at a point uniform in the disc of
      radius `payload_radius` (default half the joint radius r, 0.31 m) about P in the {P} x-y
      plane: a dead weight (its inertia is not modelled) applied as the external wrench, evaluated at
      the state each step starts from.  The payload is not observed.

    Options of a task go in `task_options` (a dict); `env.unwrapped.target` gives the current
    reference (position, rotation, velocity, angular_velocity).

    ## Episode End

    ### Termination
    The task decides.  Every task's reasons begin with the platform's limits, all failures: the
    episode terminates when, after a control step,
    1. the state is no longer finite (`"non_finite"`; the state is kept at the last finite one),
    2. the leg Jacobian's condition number exceeds `limits.max_condition` (`"singularity"`),
    3. a leg length leaves the stroke `limits.leg_length` (`"leg_stroke"`),
    4. P leaves the workspace box `limits.position_min`-`position_max`, or roll, pitch or yaw
       deviates from home by more than `limits.max_angle` (`"workspace"`),

    reasons checked in this order.  `info["termination"]` is the reason's code, a numpy int64:
    0 while the episode goes on, else the index of the reason in
    `env.unwrapped.termination_reasons` = `("", "non_finite", "singularity", "leg_stroke",
    "workspace")` followed by the task's own reasons (so `termination_reasons[code]` is its name);
    of the shipped tasks only `cueing` has one, `"motion_end"`, a success at the vehicle motion's
    last sample (its `info["is_success"]` is true; give `max_episode_steps` at least the longest
    motion's steps, or the time limit truncates the motion first).
    No NaN or inf leaves the environment: a step whose observation or reward is not finite, or
    beyond the float32 range of the returned observation, also terminates as `"non_finite"` and
    returns a finite observation (NaN as 0, the rest clipped to the float32 range) and a finite
    reward; a start state whose observation is not finite ends the episode so at the first step.

    `terminate_on` chooses which of the platform's limits end an episode (see Constraint Costs):
    left out of it, `leg_length` and `workspace` no longer end one (their reasons stay in
    `termination_reasons`, never reported); each other constraint in it ends an episode that the
    task did not end at that step, as a failure that pays `termination_cost`, with the
    constraint's name as its reason, after the task's own in `termination_reasons` (e.g.
    `terminate_on=("leg_length", "leg_velocity", "workspace")` adds `"leg_velocity"`).

    ### Truncation
    Only by the time limit: 500 steps (5 s at the default `control_dt`), set by `max_episode_steps`
    of `gymnasium.make` (the `TimeLimit` wrapper) or of `gymnasium.make_vec`.

    ## Constraint Costs

    Every step's `info` holds the platform's constraint costs, the safety-gymnasium convention for
    constrained RL (a Lagrangian PPO or any CMDP learner reads them): `cost_<constraint>` is 1.0
    when after the step any leg (any workspace axis) is outside that limit, else 0.0, and `cost`
    their sum, 0.0 inside every limit; numpy float64, never NaN (a value that is not finite
    violates its limit).  The constraints are those whose limit the platform's config sets (the
    `limits` section; `dasgupta1998` has the first three of these, the shipped `motion_simulator`
    all eight):

    | key | violated when | limit (`limits` key, units) |
    |---|---|---|
    | `cost_leg_length` | a leg length outside the stroke | `leg_length`, m |
    | `cost_leg_force` | a leg force applied over the step outside the force range | `leg_force`, N |
    | `cost_workspace` | P outside the workspace box, or roll, pitch or yaw further than `max_angle` from home | `workspace.position_min`, `position_max`, m; `workspace.max_angle`, rad |
    | `cost_leg_velocity` | a leg rate beyond the bound | `leg_velocity`, m/s |
    | `cost_leg_acceleration` | a leg's mean acceleration over the step beyond the bound | `leg_acceleration`, m/s^2 |
    | `cost_force_rate` | a leg force's change over the step, per s, beyond the bound (0 at an episode's first step) | `force_rate`, N/s |
    | `cost_universal_joint` | a leg's angle to its universal joint's mounting axis beyond the cone | `universal_joint.max_angle`, rad |
    | `cost_spherical_joint` | a leg's angle to its spherical joint's mounting axis beyond the cone | `spherical_joint.max_angle`, rad |

    The legs are measured on the nominal geometry, as the leg sensors are; docs/physics.md,
    "Limits and constraint costs", defines each value (eqs. L0-L7).  The vector environment's
    infos hold the same keys as (N,) arrays, and `StewartPlatformSB3VecEnv`'s row infos the row's
    floats.  By default only `leg_length` and `workspace` end an episode (as the termination
    reasons `leg_stroke` and `workspace`): the other constraints cost without ending it, unless
    `terminate_on` names them (see Episode End).  `action_delay=d` applies at every step the action
    given d steps earlier (the first d steps of an episode apply the zero action, the one a row
    starts with), as a command reaches a real machine's drives through its fieldbus; the reward's
    control term is of the action applied.

    ## Arguments

    `gymnasium.make("StewartPlatform-v1", **kwargs)` and `StewartPlatformEnv(**kwargs)` take these
    keyword arguments (`inspect.signature` shows them), grouped into frozen records of
    `stewart_env.envs.config` (physics, task, actuator, constraints, observation, rendering) that check each at
    construction against a finite range (outside it, or of the wrong kind, a `ValueError` naming
    the argument); an unknown keyword raises, as Python does, `StewartPlatformEnv.__init__() got
    an unexpected keyword argument '...'` (an error that is both a `TypeError` and a `ValueError`):

    | argument | default | description |
    |---|---|---|
    | `model` | `"improved"` | dynamics model: `"improved"`, `"improved_centroidal"`, `"classical"`, optionally with switches such as `"+c1"`; `"mujoco"` is another spelling of `plant="mujoco"` (with the `"improved"` model) |
    | `plant` | `"closed_form"` | what simulates the platform: `"closed_form"` (`model` integrated with RK4) or `"mujoco"` (MuJoCo simulating the same mechanism, needs the `mujoco` extra) |
    | `platform` | `"dasgupta1998"` | a shipped config name, a YAML path, or a `PlatformParams`; a string with no `/` and no `.yaml`/`.yml` suffix is always a shipped config's name, whatever the working directory holds |
    | `control_dt` | `0.01` | s per environment step, 1e-6 to 10 |
    | `physics_dt` | `0.001` | s per RK4 substep; `control_dt` must be a whole multiple of it, at most 10^6 substeps |
    | `randomization` | `None` | domain randomisation spec, e.g. `{"platform.mass": (0.8, 1.2), "legs.mass": (0.9, 1.1), "inertia": (0.9, 1.1), "com": (0.9, 1.1), "damping": (0.5, 2.0)}` |
    | `task` | `"setpoint"` | `"setpoint"`, `"tracking"`, `"disturbance"`, `"hold"`, `"cueing"` (or a `Task` subclass) |
    | `task_options` | `None` | dict of the task's options, its reward weights included (see Starting State, Rewards and `stewart_env.tasks`) |
    | `version` | `1` | the environment's version, 0 to 1, set by the id `StewartPlatform-v<version>`: its tasks' defaults (see Version History) |
    | `actuator_tau` | `0.0` | s, first-order actuator lag time constant, 0 to 100; 0 applies the commanded forces directly |
    | `action_mode` | `"force"` | `"force"` (six leg-force set points over `limits.leg_force`, N), `"leg_length"` (six leg-length set points over the stroke `limits.leg_length`, m, each tracked by a leg servo at the physics rate) or `"pose"` (a pose set point over the workspace box `limits.position_min`..`position_max`, m, and `home_rpy` +- `max_angle`, rad, tracked at the physics rate by `pose_law`); see Action Space |
    | `pose_law` | `"ik"` | the pose mode's inner loop: `"ik"` (inverse kinematics into the leg servos), `"pd_gravity"` (task-space PD with gravity compensation) or `"computed_torque"`, on the nominal model |
    | `actuator` | `None` | `"ideal"` (a force source), `"lag"` (first-order lag of `actuator_tau`), `"electric"` (motor and ball screw) or `"hydraulic"` (valve-controlled cylinder), the last two from the platform's `actuators:` section; None: `"lag"` when `actuator_tau` > 0, else `"ideal"` |
    | `observe_actuators` | `False` | append the states a drive reports to the observation: motor currents (electric, over the current limit) or chamber pressures A and B (hydraulic, over the supply-return span) |
    | `terminate_on` | `('leg_length', 'workspace')` | the constraints that end an episode, a tuple of the platform's: `'leg_length'`, `'leg_velocity'`, `'leg_acceleration'`, `'leg_force'`, `'force_rate'`, `'universal_joint'`, `'spherical_joint'`, `'workspace'` (see Constraint Costs); `()` for none |
    | `action_delay` | `0` | control steps between the action and the actuators, 0 to 1000 (see Constraint Costs) |
    | `observation_mode` | `"pose"` | `"pose"` (pose and twist) or `"sensors"` (leg lengths and rates) |
    | `normalize_observation` | `True` | scale the observation by the platform's limits (see Observation Space) |
    | `observation_noise` | `0.0` | Gaussian noise std in observation units, 0 to 100: a number, or a dict term name -> std |
    | `observation_delay` | `0` | control steps between measurement and observation, 0 to 1000 |
    | `error_integral` | `False` | observe the time integral of the pose error (see Observation Space) |
    | `error_integral_limit` | `0.1` | s, anti-windup bound T of the error integral: +-T h (position), +-T A (orientation); 1e-6 to 1e6 |
    | `error_integral_band` | `None` | integrate an error component only within this fraction (0 to 1e6) of its scale (h, A); None: always |
    | `render_mode` | `None` | `"rgb_array"` or `"human"` |
    | `width` | `480` | rendered frame width, px, 1 to 4096 |
    | `height` | `480` | rendered frame height, px, 1 to 4096 |

    Domain randomisation (`randomization`) draws, at every reset, one factor per key uniformly in its
    range and scales the nominal parameters by it: keys `platform.`, `upper_leg.`, `lower_leg.` or
    `legs.` followed by `mass`, `inertia` or `com`; `mass`, `inertia`, `com` for every body; `damping`
    or `damping.universal`, `.prismatic`, `.spherical`.  Unknown keys or bad ranges raise
    `ValueError`.  The reset `info` then holds `randomization` (the factors, name -> number);
    `env.unwrapped.episode_params` is the episode's `PlatformParams` and `env.unwrapped.model` its
    dynamics model.  The tasks' options have ranges of their own (see `stewart_env.tasks`).

    Infos hold only numpy numbers (as torchrl's info readers need): a step's `info` has
    `reward_<term>` and `time` (and `closure_error` on the MuJoCo plant) as float64,
    `termination` as an int64 code, and the errors and verdict of the task's success criterion
    (`env.unwrapped.task.success_criterion`, the evaluation harness's): `position_error`, `|e_p|`
    in m, and `orientation_error`, the angle of `e_o` in rad, as float64 (the true errors after the
    step, not the noisy observation: the numbers the harness measures, to the last bit), and
    `is_success`, a numpy bool: whether the episode, were it to end at this step (at time t_k),
    succeeds: it was not terminated, and every sample of its final tenth (of the errors at reset
    and after each step, those at t >= 0.9 t_k, and at least the last) lies within 2 mm and
    0.01 rad.  At the step that ends an episode, by the time limit or by a termination (then
    always False), it is the verdict on the whole episode, as stable-baselines3's `Monitor`
    (`info_keywords=("is_success",)`) and `EvalCallback` read it; before, it says whether the
    episode so far meets the criterion (a set-point episode turns True once the platform has held
    the band over the latest tenth of the time elapsed).
    `step()` before the first `reset()` raises `gymnasium.error.ResetNeeded`.
    `reset()` takes no `options` (the vector environment one, `reset_mask`): any, or an `options`
    that is not a dict or None, raises a `ValueError` naming `options`.
    `copy.deepcopy(env)` and `pickle` give an environment that continues bit for bit as the
    original, at any point of an episode (on MuJoCo too).

    Rendering: `render_mode="rgb_array"` returns (height, width, 3) uint8 frames (headless; works with
    `gymnasium.wrappers.RecordVideo`), `"human"` draws in a window.  Legs run from blue (minimum force)
    through dark grey (zero) to red (maximum), with a colour bar in N; the target pose is a dashed
    green ghost.  On a machine without a display, `"human"` warns once (through
    Gymnasium's logger) and draws nothing, and `render()` returns None.  `metadata["render_fps"]`
    is `1 / control_dt`.

    Vector environment: `gymnasium.make_vec("StewartPlatform-v1", num_envs=N,
    vectorization_mode="vector_entry_point", **kwargs)` steps all N platforms in one compiled call,
    with Gymnasium's next-step autoreset (`autoreset_mode` also takes `"SameStep"` and `"Disabled"`);
    `reset(seed=s)` seeds row i with s + i, so row i reproduces the single environment reset with
    seed s + i.  Each row is a sub-environment to Gymnasium's `call`, `get_attr` and `set_attr`
    (e.g. `get_attr("state")`, `call("render")`; `set_attr` sets a row's `np_random`, or one value
    shared by all rows), and `render()` gives one frame per row (drawn when first indexed, so that
    `gymnasium.wrappers.vector.RecordVideo` works).  Step infos are arrays with Gymnasium's masks,
    `termination` an int64 array with 0 for rows that go on, `is_success` a bool array.
    `stewart_env.envs.StewartPlatformSB3VecEnv(num_envs=N, **kwargs)` is the same batch behind
    stable-baselines3's `VecEnv` API; its infos hold `is_success` at the end of a row's episode.

    Other attributes of `env.unwrapped`: `state` (position, rotation, velocity, angular_velocity),
    `target`, `model` (the `Dynamics`), `plant` (what simulates the platform, named by `plant.name`),
    `episode_params`, `leg_forces` (N, applied over the last step), `external_wrench`,
    `leg_lengths`, `platform`, `task`, `dt`, and `set_state(...)`.  All randomness
    comes from `env.np_random`, so a seed fixes an episode bit for bit.

    ## Example

    ```pycon
    >>> import gymnasium as gym, numpy as np
    >>> env = gym.make("StewartPlatform-v1", task="setpoint")
    >>> observation, info = env.reset(seed=0)
    >>> observation.shape, env.action_space.shape
    ((21,), (6,))
    >>> observation, reward, terminated, truncated, info = env.step(np.zeros(6, np.float32))
    >>> terminated, truncated, int(info["termination"])
    (False, False, 0)
    >>> env.close()

    ```

    ## Version History

    Both ids stay registered: `gymnasium.make("StewartPlatform-v0", ...)` gives the earlier
    reward (Gymnasium warns that the id is out of date), and so do the vector environment and
    `StewartPlatformSB3VecEnv` with `version=0`.  The classes give the current version.

    * v1: the `tracking` and `disturbance` tasks' default position and orientation reward scales
      are 0.01 m and 0.02 rad, so that the millimetre errors these tasks are about weigh in the
      reward (0.05 m and 0.1 rad in v0, as the `setpoint` and `hold` tasks' still are).  Options
      given in `task_options` win over either version's defaults, so
      `task_options={"position_reward_scale": 0.05, "orientation_reward_scale": 0.1}` on v1 is v0's
      reward.  The dynamics, observations, terminations and the other tasks are those of v0.
      From 2026-11-24 until v1 was registered, the id v0 gave this reward: agents trained and
      results measured in those days on these two tasks are of v1's reward.
    * v0: initial version, with every task's reward scales 0.05 m and 0.1 rad.  Since 2026-11-25
      the `plant` argument names what simulates the platform (`"closed_form"` or `"mujoco"`;
      `model="mujoco"` still means `plant="mujoco"` on the `"improved"` model), on both ids.
    """  # noqa: D415  (the env card opens with its first section's heading, as Gymnasium's cards do)

    _rows = 0  # BatchAttributes: the single platform, no batch axis
    metadata = {"render_modes": list(RENDER_MODES), "render_fps": 100.0}

    @with_signature()
    def __init__(self, **arguments: Any):
        check_arguments(type(self).__name__, arguments)
        config = EnvConfig.of(**arguments)
        self._core = core = PlatformBatch(1, config)
        self.render_mode = config.render.render_mode
        self.metadata = {**type(self).metadata, "render_fps": core.render_fps}
        self.action_space = spaces.Box(-1.0, 1.0, (6,), np.float32)
        self.observation_space = spaces.Box(-np.inf, np.inf, (core.obs_dim,), np.float32)
        self._rngs: tuple[np.random.Generator, ...] = ()

    # -- the Gymnasium API --------------------------------------------------------------------------

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        """Start a new episode (Gymnasium's ``Env.reset``).

        Args:
            seed: the seed of the environment's generator, or None to go on with it.
            options: must be None or empty: the environment takes no reset options.

        Returns:
            The start observation (D,) float32 and the reset's info dict.

        Raises:
            TypeError: ``options`` not a mapping (an ``ArgumentError``, a ``UsageError``).
            ValueError: a reset option (the message names ``options``).
        """
        reset_options(options)  # takes none; refused before the seed changes anything
        super().reset(seed=seed)
        self._rngs = (self.np_random,)
        info = self._core.reset_rows(_ROW0, self._rngs)[0]
        self._reset_done = True
        if self.render_mode == "human":
            self.render()
        return self._core.observation[0].astype(np.float32), info

    def step(self, action):
        """One control step (Gymnasium's ``Env.step``).

        Args:
            action: (6,) the leg forces scaled to [-1, 1] (clipped there), finite.

        Returns:
            The tuple (observation (D,) float32, reward, terminated, truncated, info); truncation
            is the TimeLimit wrapper's.

        Raises:
            TypeError: an action that is not real numbers (an ``ArgumentError``, a ``UsageError``).
            ValueError: an action of another shape, or not finite.
            gymnasium.error.ResetNeeded: a step before the first reset.
        """
        self._check_reset()
        core = self._core
        if core.checks_action and type(action) is np.ndarray and action.dtype in _FLOATS and action.shape == (6,):
            # a float array of the right shape as it is: the compiled step widens float32 exactly and
            # refuses (doing nothing) an action that is not finite, which check_action then names
            outcome = core.step(action, self._rngs, reuse=True)
            if outcome is None:
                check_action(action, (6,))
        else:
            outcome = core.step(check_action(action, (6,)).reshape(1, 6), self._rngs, reuse=True)
        reward, code, terms, observation = outcome
        info = row_info(
            terms,
            code,
            core.time,
            core.plant.closure_error,
            0,
            core.track_success_of_row(0, code),
            core.costs.info(0),
            core.task.step_info(),
        )
        if self.render_mode == "human":
            self.render()
        return observation[0].copy(), float(reward[0]), bool(code[0]), False, info

    def render(self):
        """The frame now, as ``render_mode`` says (an RGB array, or drawn in a window), or None without one."""
        if self.render_mode is None:
            gym.logger.warn(
                "render() called without a render_mode; pass render_mode='rgb_array' or 'human' to gymnasium.make"
            )
            return None
        return self._draw()

    def close(self):
        """Close the renderer's window, if any."""
        self._close_renderer()

    # -- introspection: see BatchAttributes ------------------------------------------------------

    def set_state(self, position, rotation, velocity=None, angular_velocity=None) -> None:
        """Put the platform in a state (in {B}; velocities default to zero); the episode goes on
        from it at the next step.

        Args:
            position: (3,) m, the position of P's origin in {B}.
            rotation: (3,3) rotation matrix, columns = {P} axes; orthonormal.
            velocity: (3,) m/s, the velocity of P's origin in {B} (default zero).
            angular_velocity: (3,) rad/s, the platform's angular velocity in {B} (default zero).

        Raises:
            TypeError: a value that is not real numbers (an ``ArgumentError``, a ``UsageError``).
            ValueError: a value of another shape or not finite, or a rotation not orthonormal.
        """
        values = {
            "position": (position, (3,)),
            "rotation": (rotation, (3, 3)),
            "velocity": (np.zeros(3) if velocity is None else velocity, (3,)),
            "angular_velocity": (np.zeros(3) if angular_velocity is None else angular_velocity, (3,)),
        }
        checked = {name: real_array(name, value, shape) for name, (value, shape) in values.items()}
        R = checked["rotation"]
        check_rotation("rotation", R[None])  # the physics API's own test, so both accept the same states
        c = self._core
        c.position[0], c.rotation[0] = checked["position"], R
        c.velocity[0], c.angular_velocity[0] = checked["velocity"], checked["angular_velocity"]
        # the leg accelerations of the next step are measured from this state's leg rates
        c.costs.set_state(_ROW0, PlatformState(*(x[_ROW0] for x in c._state)))
