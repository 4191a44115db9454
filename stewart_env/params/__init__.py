"""Platform parameters of the 6-UPS Stewart platform: the config schema, loading and validation.

A platform is described by one config (a YAML file or a plain dict) with these keys:

    base_joints: [[x, y, z], ...]        # six rows: b_i in {B}, m
    platform_joints: [[x, y, z], ...]    # six rows: p_i in {P}, m
    hooke_axes: [[kx, ky, kz], ...]      # six rows or one shared row: fixed U-joint axes k_i in {B}
    platform:  {mass: .., com: [..], inertia: ..}   # com in {P}; inertia about the CoM, {P} axes
    upper_leg: {mass: .., com: [..], inertia: ..}   # one mapping for all legs, or a list of six
    lower_leg: {mass: .., com: [..], inertia: ..}   # same
    damping:   {universal: Cu, prismatic: Cp, spherical: Cs}
    gravity: [0, 0, -9.81]               # optional, m/s^2 in {B}
    limits:                              # optional; each entry optional (defaults below)
      leg_length: [min, max]             # actuator stroke, m
      leg_force: [min, max]              # actuator force range, N
      workspace: {position_min: [..], position_max: [..], max_angle: rad}
      max_condition: 1000.0              # bound on the leg Jacobian's condition number
      leg_velocity: v_max                # bound on |dL_i/dt|, m/s
      leg_acceleration: a_max            # bound on |d2L_i/dt2| over a control step, m/s^2
      force_rate: fdot_max               # bound on |dF_i/dt| over a control step, N/s
      universal_joint: {max_angle: rad, axes: [..]}   # cone of the base joints; axes in {B}
      spherical_joint: {max_angle: rad, axes: [..]}   # cone of the platform joints; axes in {P}
    home: {position: [x, y, z], rpy: [roll, pitch, yaw]}   # optional (see below)
    actuators:                           # optional: the legs' actuator parameter sets, SI units
      electric: {lead: .., torque_constant: .., ...}       # stewart_env.params.actuators
      hydraulic: {bore_diameter: .., supply_pressure: .., ...}

`inertia` is a 3x3 nested list or a 3-list, the shorthand for a diagonal matrix. The leg CoMs are
given in the leg frame {D_i} = [e_i, y_i, z_i]: the upper leg's from the platform joint P_i
(CoM = P_i + T_i r_u0), the lower leg's from the base joint B_i (CoM = B_i + T_i r_d0).
Orientations use R = Rz(yaw) Ry(pitch) Rx(roll).

Defaults when `home` or `limits` (or any entry of `limits`) is missing, so that a platform can be
built from the physical keys alone:

- home: position [0, 0, 0], rpy [0, 0, 0], accepted only if that pose is valid (every leg of
  nonzero length, no Hooke axis parallel to its leg); otherwise loading fails and asks for `home`.
  A `home` given without `rpy` takes rpy [0, 0, 0].
- limits.leg_length: (0.8 min_i L_i, 1.2 max_i L_i) with L_i the leg lengths at the home pose.
- limits.leg_force: (-10 W, 10 W), W = (m_p + 6 (m_u + m_d)) |g| / 6 the weight share of one leg
  (|g| = 9.81 when gravity is zero, so that the range is never empty).
- limits.workspace.position_min / position_max: the home position -/+ 0.5 mean_i L_i on each axis.
- limits.workspace.max_angle: 0.5 rad.  limits.max_condition: 1000.
- limits.leg_velocity, leg_acceleration, force_rate and each joint's max_angle: no bound (each, when
  given, > 0; a cone's max_angle in (0, pi]). A joint's axes (six rows or one shared row, normalised
  on load): its mounting axis, the leg direction at the centre of its cone; the z axis of {B}
  (universal joints) or {P} (spherical joints) by default. The cone angle of leg i is the angle
  between its axis e_i and the mounting axis (R c_i for a spherical joint); the home pose must
  keep every cone angle within its bound.

Every number must be a real number (not a boolean), finite as a float64 and at most 1e12 in
magnitude, so that nothing overflows in the dynamics; the platform's mass must be at least 1e-6 kg
and its principal moments of inertia at least 1e-15 kg m^2.

Every invalid input raises `ConfigError` (a `ValueError`) whose message starts with the key path
of the offending value, e.g. ``upper_leg[2].inertia: not symmetric`` or
``base_joints[3][1]: not a finite number (inf)``. Leg indices in messages count from 0, like the
rows of the arrays. Messages quote at most a short excerpt of a value, never a whole file.

The home pose must be valid: every leg of nonzero length, no Hooke axis parallel to its leg, the
leg lengths inside limits.leg_length and the position inside the workspace box. The leg
Jacobian's condition number there must be at most limits.max_condition: the model built on the
platform (`stewart_env.dynamics.Dynamics`, and so every environment) checks it, with the same
`ConfigError`.

Names: a string with no path separator and no .yaml/.yml suffix is a shipped platform's name,
whatever the working directory holds; anything else is a file (`load_platform`).

Files: `load_platform` and `PlatformParams.from_yaml` read only regular files named *.yaml or
*.yml of at most 1 MB (`MAX_CONFIG_BYTES`), with YAML's safe loader, nesting at most 32 levels
deep and at most 5000 values once aliases are expanded; a key given twice in one mapping is an
error (a merge, <<: *anchor, may still be overridden).

The package's modules, one job each: ``checks`` (`ConfigError` and the checks of raw values),
``bodies`` (RigidBody, Damping, Limits), ``actuators`` (the ``actuators:`` section's parameter
sets: ActuatorSets of ElectricParams and HydraulicParams), ``platform``
(PlatformParams), ``reader`` (the bounded reader of config files) and ``shipped`` (the shipped
configs by name, `load_platform`).
"""

from stewart_env.params.actuators import ActuatorSets, ElectricParams, HydraulicParams
from stewart_env.params.bodies import Damping, Limits, RigidBody
from stewart_env.params.checks import ConfigError

# re-exported (``name as name``) outside __all__: the package's modules and tests import them from here
from stewart_env.params.platform import N_LEGS as N_LEGS
from stewart_env.params.platform import PlatformParams
from stewart_env.params.reader import MAX_CONFIG_BYTES as MAX_CONFIG_BYTES
from stewart_env.params.shipped import available_platforms, load_platform
from stewart_env.params.shipped import config_dir as config_dir

__all__ = [
    "ConfigError",
    "RigidBody",
    "Damping",
    "Limits",
    "ElectricParams",
    "HydraulicParams",
    "ActuatorSets",
    "PlatformParams",
    "load_platform",
    "available_platforms",
]

# Shown, documented and pickled under this package, their public home, whichever module defines them.
for _public in (
    ConfigError,
    RigidBody,
    Damping,
    Limits,
    ElectricParams,
    HydraulicParams,
    ActuatorSets,
    PlatformParams,
    load_platform,
    available_platforms,
):
    _public.__module__ = __name__
del _public
