"""Driving manoeuvres of a mid-size car: a single-track (bicycle) model steered by a pure-pursuit
driver along a path, with the body's roll and pitch on their suspensions.

The car (:data:`CAR`) is a linear-in-slip single-track model (Riekert and Schunck 1940; Rajamani,
*Vehicle Dynamics and Control*, 2nd ed., Springer 2012, section 2.3) whose tyres' lateral forces
saturate at the road's friction (``F = F_max tanh(C alpha / F_max)``); its parameters are
representative of a mid-size passenger car, of the order of Rajamani's examples, not the data of a
particular car.  The forward speed follows a commanded longitudinal acceleration.  The driver is
a pure pursuit (Coulter, CMU-RI-TR-92-01, 1992) aiming at the path's point a preview time ahead,
through a first-order steering lag.  The body rolls and pitches on its suspension as a damped
second-order system driven by the lateral and longitudinal accelerations at the sprung mass's
height; the motion is given at the driver's head (:data:`HEAD`), a point fixed in the body.

Manoeuvres (each seeded; the ranges drawn are in the docstrings and in docs/guides/cueing.md):

- ``double_lane_change``: the track of ISO 3888-1 (the lengths of its six sections, 15, 30, 25,
  25, 15 and 15 m, and its lateral offset of 3.5 m), the driver following the gates' centre line
  with a cosine transition through each transition section;
- ``slalom``: a sine path through cones;
- ``braking`` and ``acceleration``: straight, with the longitudinal acceleration commanded.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from stewart_env.tasks.cueing.motion import STANDARD_GRAVITY, VehicleMotion
from stewart_env.tasks.cueing.motions.kinematics import (
    at_head,
    euler_rates_to_body,
    motion,
    motion_rng,
    rotate_to_body,
    smoothstep,
    uniform,
)

__all__ = [
    "CAR",
    "HEAD",
    "ISO_3888_1_OFFSET",
    "ISO_3888_1_SECTIONS",
    "Car",
    "acceleration",
    "braking",
    "double_lane_change",
    "simulate",
    "slalom",
]


@dataclass(frozen=True)
class Car:
    """The single-track model's parameters (SI units).

    Attributes:
        mass: the car's mass, kg.
        yaw_inertia: about the vertical axis through the centre of mass, kg m².
        front_axle: the front axle ahead of the centre of mass, m.
        rear_axle: the rear axle behind the centre of mass, m.
        front_cornering: the front axle's cornering stiffness (both tyres), N/rad.
        rear_cornering: the rear axle's, N/rad.
        friction: the tyre-road friction coefficient.
        sprung_height: the sprung mass's centre above the roll and pitch axes, m.
        roll_gradient: the steady body roll per lateral acceleration, rad/(m/s²).
        roll_frequency: the roll mode's natural frequency, Hz.
        pitch_gradient: the steady body pitch per longitudinal acceleration, rad/(m/s²).
        pitch_frequency: the pitch mode's natural frequency, Hz.
        suspension_damping: the damping ratio of both modes.
        steering_lag: the driver's and steering's first-order time constant, s.
        max_steer: the largest road-wheel angle, rad.
    """

    mass: float = 1500.0
    yaw_inertia: float = 2500.0
    front_axle: float = 1.2
    rear_axle: float = 1.5
    front_cornering: float = 90_000.0
    rear_cornering: float = 110_000.0
    friction: float = 1.0
    sprung_height: float = 0.5
    roll_gradient: float = 0.06 / STANDARD_GRAVITY
    roll_frequency: float = 1.5
    pitch_gradient: float = 0.025 / STANDARD_GRAVITY
    pitch_frequency: float = 1.8
    suspension_damping: float = 0.5
    steering_lag: float = 0.1
    max_steer: float = 0.5

    @property
    def wheelbase(self) -> float:
        """The distance between the axles, m."""
        return self.front_axle + self.rear_axle


#: The car of every driving manoeuvre.
CAR = Car()
#: The driver's head from the car's centre of mass (x forward, y left, z up), m: a left-hand-drive
#: driver's seat, slightly behind the centre of mass and 0.6 m above it.
HEAD = (-0.2, 0.37, 0.6)
#: The lengths of the six sections of the ISO 3888-1 double lane change track, m.
ISO_3888_1_SECTIONS = (15.0, 30.0, 25.0, 25.0, 15.0, 15.0)
#: The lateral offset of its third section from the first and fifth, m.
ISO_3888_1_OFFSET = 3.5


def _second_order(drive: np.ndarray, gain: float, frequency: float, damping: float, dt: float) -> np.ndarray:
    """The response of ``x'' + 2 zeta w x' + w² x = gain w² drive`` from rest (semi-implicit Euler)."""
    w = 2.0 * math.pi * frequency
    x, v = 0.0, 0.0
    out = np.empty_like(drive)
    for k, u in enumerate(drive):
        v += dt * (w * w * (gain * u - x) - 2.0 * damping * w * v)
        x += dt * v
        out[k] = x
    return out


def simulate(
    path, speed0: float, longitudinal: np.ndarray, dt: float, preview: float, car: Car = CAR
) -> dict[str, np.ndarray]:
    """Drive the car along ``path`` with the longitudinal acceleration ``longitudinal``.

    Args:
        path: a function of the distance along x (m, arrays) giving the path's lateral position y (m).
        speed0: the initial forward speed, m/s.
        longitudinal: (T,) the commanded longitudinal acceleration, m/s² (the speed stays >= 0).
        dt: the sampling period, s (the model is integrated at dt / 4).
        preview: the driver's preview time, s (the pure pursuit's look-ahead distance is
            ``max(3 m, preview * speed)``).
        car: the car.

    Returns:
        The arrays (T,) ``ax``, ``ay`` (the centre of mass's acceleration in the heading frame,
        m/s²), ``yaw_rate`` (rad/s), ``speed`` (m/s), ``x``, ``y`` (m), ``steer`` (rad).
    """
    n = len(longitudinal)
    sub = 4
    h = dt / sub
    c = car
    fz_front = c.mass * STANDARD_GRAVITY * c.rear_axle / c.wheelbase
    fz_rear = c.mass * STANDARD_GRAVITY * c.front_axle / c.wheelbase
    max_front, max_rear = c.friction * fz_front, c.friction * fz_rear
    u, vy, r, psi, x, y, steer = float(speed0), 0.0, 0.0, 0.0, 0.0, float(path(np.array([0.0]))[0]), 0.0
    out = {key: np.empty(n) for key in ("ax", "ay", "yaw_rate", "speed", "x", "y", "steer")}
    for k in range(n):
        ax_cmd = float(longitudinal[k])
        ay = 0.0
        for _ in range(sub):
            # pure pursuit from the rear axle to the path's point one look-ahead distance ahead
            look = max(3.0, preview * u)
            xr, yr = x - c.rear_axle * math.cos(psi), y - c.rear_axle * math.sin(psi)
            xt = xr + look
            yt = float(path(np.array([xt]))[0])
            alpha = math.atan2(yt - yr, xt - xr) - psi
            target = math.atan(2.0 * c.wheelbase * math.sin(alpha) / look)
            target = max(-c.max_steer, min(c.max_steer, target))
            steer += h * (target - steer) / c.steering_lag
            if u > 0.5:
                slip_front = steer - (vy + c.front_axle * r) / u
                slip_rear = -(vy - c.rear_axle * r) / u
                force_front = max_front * math.tanh(c.front_cornering * slip_front / max_front)
                force_rear = max_rear * math.tanh(c.rear_cornering * slip_rear / max_rear)
                vy_dot = (force_front * math.cos(steer) + force_rear) / c.mass - u * r
                r_dot = (c.front_axle * force_front * math.cos(steer) - c.rear_axle * force_rear) / c.yaw_inertia
            else:  # too slow for the slip angles: rolling without slip
                vy_dot, r_dot = -vy / h, -r / h
            ay = vy_dot + u * r
            vy += h * vy_dot
            r += h * r_dot
            u = max(0.0, u + h * ax_cmd)
            psi += h * r
            x += h * (u * math.cos(psi) - vy * math.sin(psi))
            y += h * (u * math.sin(psi) + vy * math.cos(psi))
        out["ax"][k] = ax_cmd - vy * r
        out["ay"][k] = ay
        out["yaw_rate"][k], out["speed"][k], out["x"][k], out["y"][k], out["steer"][k] = r, u, x, y, steer
    return out


def _at_driver(name: str, seed: int, dt: float, run: dict, car: Car = CAR, **meta) -> VehicleMotion:
    """The motion at the driver's head of a simulated run: the body's roll and pitch on their
    suspensions, the specific force rotated into the body and moved to the head."""
    # a left turn (ay > 0) throws the body outwards, raising its left side (roll > 0); braking
    # (ax < 0) dips the nose (pitch > 0)
    roll = _second_order(run["ay"], car.roll_gradient, car.roll_frequency, car.suspension_damping, dt)
    pitch = _second_order(-run["ax"], car.pitch_gradient, car.pitch_frequency, car.suspension_damping, dt)
    heading = np.stack([run["ax"], run["ay"], np.full_like(run["ax"], STANDARD_GRAVITY)], axis=1)
    omega = euler_rates_to_body(roll, pitch, dt, run["yaw_rate"])
    force = at_head(rotate_to_body(heading, roll, pitch), omega, HEAD, dt)
    return motion(name, seed, dt, force, omega, **meta)


def _samples(duration: float, dt: float) -> np.ndarray:
    return np.arange(int(round(duration / dt)) + 1) * dt


def double_lane_change(seed: int, dt: float = 0.01) -> VehicleMotion:
    """The ISO 3888-1 double lane change at a steady speed.

    Drawn: the speed U(60, 80) km/h (the standard's test speed is 80 km/h), the straight run before
    the first gate U(10, 30) m, the driver's preview time U(0.6, 0.8) s.  The path is the gates'
    centre line, a cosine transition through sections 2 and 4; the run ends 2 s after the track.
    The pure-pursuit driver overshoots the offset lane by 0.5 to 1 m (more at the higher speeds):
    the motion is a driver's through the track's geometry, not a run clear of every cone.

    Args:
        seed: the seed.
        dt: the sampling period, s.

    Returns:
        The motion at the driver's head.
    """
    rng = motion_rng("double_lane_change", seed)
    speed = uniform(rng, 60.0, 80.0) / 3.6
    lead = uniform(rng, 10.0, 30.0)
    preview = uniform(rng, 0.6, 0.8)
    edges = lead + np.cumsum((0.0,) + ISO_3888_1_SECTIONS)

    def path(x):
        out_ = smoothstep(x, edges[1], ISO_3888_1_SECTIONS[1])
        back = smoothstep(x, edges[3], ISO_3888_1_SECTIONS[3])
        return ISO_3888_1_OFFSET * (out_ - back)

    t = _samples(edges[-1] / speed + 2.0, dt)
    run = simulate(path, speed, np.zeros_like(t), dt, preview)
    return _at_driver("double_lane_change", seed, dt, run, speed=speed, lead=lead, preview=preview)


def slalom(seed: int, dt: float = 0.01) -> VehicleMotion:
    """A slalom through cones at a steady speed: the path ``y = A sin(pi (x - x0) / spacing)`` for
    ``n`` cones, straight before and after.

    Drawn: the speed U(40, 70) km/h, the cone spacing U(15, 24) m, the path's peak lateral
    acceleration U(1.5, 3.5) m/s² (the driver's overshoot stays within the tyres' grip), which sets
    the amplitude ``A = a / (pi u / spacing)²`` (at most 2 m), the number of cones 4 to 7, the
    straight before U(10, 25) m, the preview time U(0.6, 0.9) s.

    Args:
        seed: the seed.
        dt: the sampling period, s.

    Returns:
        The motion at the driver's head.
    """
    rng = motion_rng("slalom", seed)
    speed = uniform(rng, 40.0, 70.0) / 3.6
    spacing = uniform(rng, 15.0, 24.0)
    peak = uniform(rng, 1.5, 3.5)
    amplitude = min(2.0, peak / (math.pi * speed / spacing) ** 2)
    cones = int(rng.integers(4, 8))
    lead = uniform(rng, 10.0, 25.0)
    preview = uniform(rng, 0.6, 0.9)
    length = cones * spacing

    def path(x):
        inside = (x >= lead) & (x <= lead + length)
        return np.where(inside, amplitude * np.sin(np.pi * (x - lead) / spacing), 0.0)

    t = _samples((lead + length) / speed + 3.0, dt)
    run = simulate(path, speed, np.zeros_like(t), dt, preview)
    return _at_driver(
        "slalom",
        seed,
        dt,
        run,
        speed=speed,
        spacing=spacing,
        amplitude=amplitude,
        cones=cones,
        lead=lead,
        preview=preview,
    )


def braking(seed: int, dt: float = 0.01) -> VehicleMotion:
    """A straight stop: the deceleration builds up, holds, and fades as the car stops.

    Drawn: the initial speed U(50, 100) km/h, the deceleration U(3, 8) m/s², its onset U(1, 3) s,
    its build-up U(0.2, 0.5) s.  The deceleration fades below 1 m/s (``d * min(1, u / 1 m/s)``: the
    brakes' release at the stop); the run ends 2 s after the car stops.

    Args:
        seed: the seed.
        dt: the sampling period, s.

    Returns:
        The motion at the driver's head.
    """
    rng = motion_rng("braking", seed)
    speed = uniform(rng, 50.0, 100.0) / 3.6
    decel = uniform(rng, 3.0, 8.0)
    onset = uniform(rng, 1.0, 3.0)
    build = uniform(rng, 0.2, 0.5)
    t = _samples(onset + build + speed / decel + 2.5, dt)
    command = -decel * smoothstep(t, onset, build)
    # the speed is integrated here once, so that the deceleration fades as the car stops
    speed_now = speed
    for k, a in enumerate(command):
        command[k] = a * min(1.0, speed_now / 1.0)
        speed_now = max(0.0, speed_now + dt * command[k])
    run = simulate(lambda x: np.zeros_like(x), speed, command, dt, 0.5)
    return _at_driver("braking", seed, dt, run, speed=speed, deceleration=decel, onset=onset, build_up=build)


def acceleration(seed: int, dt: float = 0.01) -> VehicleMotion:
    """A straight acceleration, limited by the tyres' grip then by the engine's power, with gear
    changes (the drive interrupted for 0.3 s at each).

    Drawn: the initial speed U(0, 30) km/h, the grip-limited acceleration U(2.5, 4.5) m/s², the
    power per mass U(50, 110) W/kg, the launch U(1, 2) s, the gear changes at 30, 55 and 85 km/h
    each shifted by U(-5, 5) km/h, the duration U(8, 12) s after the launch.

    Args:
        seed: the seed.
        dt: the sampling period, s.

    Returns:
        The motion at the driver's head.
    """
    rng = motion_rng("acceleration", seed)
    speed0 = uniform(rng, 0.0, 30.0) / 3.6
    grip = uniform(rng, 2.5, 4.5)
    power = uniform(rng, 50.0, 110.0)
    launch = uniform(rng, 1.0, 2.0)
    shifts = [(s + uniform(rng, -5.0, 5.0)) / 3.6 for s in (30.0, 55.0, 85.0)]
    length = uniform(rng, 8.0, 12.0)
    t = _samples(launch + length, dt)
    command = np.zeros_like(t)
    u = speed0
    shifting_until, next_shift = -1.0, 0
    while next_shift < len(shifts) and shifts[next_shift] <= u:
        next_shift += 1
    for k, tk in enumerate(t):
        if next_shift < len(shifts) and u >= shifts[next_shift]:
            shifting_until, next_shift = tk + 0.3, next_shift + 1
        drive = min(grip, power / max(u, 1e-3)) * float(smoothstep(np.array([tk]), launch, 0.4)[0])
        # the drive fades out and back in over the gear change instead of stepping
        if tk < shifting_until:
            drive *= 0.5 - 0.5 * math.cos(2.0 * math.pi * (shifting_until - tk) / 0.3 + math.pi)
        command[k] = drive
        u += dt * drive
    run = simulate(lambda x: np.zeros_like(x), speed0, command, dt, 0.5)
    return _at_driver("acceleration", seed, dt, run, speed=speed0, grip=grip, power_per_mass=power, launch=launch)
