"""Flight manoeuvres: a coordinated turn, a take-off roll, and flight in Dryden turbulence.

The motions are given at the pilot's head (:data:`PILOT_HEAD` from the centre of mass), in the
aircraft's body axes turned to the package's convention (x forward, y left, z up).

- ``coordinated_turn``: level flight at a steady airspeed V that banks to phi, holds, and rolls
  back.  In coordinated level flight (no sideslip, the altitude held) the lift alone balances
  weight and turn, so at the centre of mass ``f = (0, 0, g / cos phi)`` and
  ``omega = (phi_dot, psi_dot sin phi, psi_dot cos phi)`` with the turn rate
  ``psi_dot = g tan phi / V`` (Etkin and Reid, *Dynamics of Flight*, 3rd ed., 1996, section 4.7;
  the pitch attitude taken as zero).
- ``takeoff_roll``: a kinematic take-off of a light aircraft: thrust less drag and rolling
  resistance along the runway, with the runway's roughness; rotation at V_R to the climb attitude;
  lift-off and the flight path's pull-up to the climb angle.
- ``turbulence``: steady level flight of a light aircraft (:data:`AIRCRAFT`) through gusts of
  the Dryden model of MIL-F-8785C (section 3.7.2.4; MIL-HDBK-1797 appendix A repeats it), at low
  altitude (its scales and intensities below 1000 ft).  The aircraft's response is its plunge and
  sideslip only, at a fixed attitude: the specific force changes with the gusts' lift, side force
  and drag (the lift, side-force and drag slopes) as the aircraft's velocity follows the gusts,
  and the angular velocity is the air mass's rotation (the rotary gusts) through a first-order
  lag of :data:`ROTARY_LAG`; the aircraft's short-period and Dutch-roll modes are not modelled.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from stewart_env.tasks.cueing.motion import STANDARD_GRAVITY, VehicleMotion
from stewart_env.tasks.cueing.motions.kinematics import at_head, motion, motion_rng, smoothstep, uniform


def _scipy_signal():
    """scipy.signal, imported when a motion first needs it: its import takes about a second."""
    import scipy.signal

    return scipy.signal


__all__ = ["AIRCRAFT", "PILOT_HEAD", "Aircraft", "coordinated_turn", "dryden_gusts", "takeoff_roll", "turbulence"]

#: The pilot's head from the centre of mass (x forward, y left, z up), m: a light aircraft's
#: left seat.
PILOT_HEAD = (1.0, 0.3, 0.5)
#: The time constant of the aircraft's rotation following the air mass's (its roll, pitch and yaw
#: damping taken as one first-order lag), s.
ROTARY_LAG = 0.3
#: Air density at sea level (ISA), kg/m³.
AIR_DENSITY = 1.225
_FEET = 0.3048
_KNOTS = 0.514444


@dataclass(frozen=True)
class Aircraft:
    """A light aircraft's parameters for the gusts' loads (of the order of a Cessna 172).

    Attributes:
        mass: kg.
        wing_area: m².
        span: m.
        lift_slope: the lift coefficient's slope, 1/rad.
        side_force_slope: the side-force coefficient's slope with sideslip (its magnitude), 1/rad.
        drag_coefficient: the drag coefficient in cruise.
    """

    mass: float = 1043.0
    wing_area: float = 16.2
    span: float = 11.0
    lift_slope: float = 4.9
    side_force_slope: float = 0.31
    drag_coefficient: float = 0.03


#: The aircraft of the turbulence.
AIRCRAFT = Aircraft()


def _samples(duration: float, dt: float) -> np.ndarray:
    return np.arange(int(round(duration / dt)) + 1) * dt


def coordinated_turn(seed: int, dt: float = 0.01) -> VehicleMotion:
    """A level coordinated turn: straight, roll-in, bank held, roll-out, straight.

    Drawn: the airspeed V U(50, 130) m/s, the bank angle U(15, 45) degrees to the left or the right,
    the roll-in and roll-out each over U(2, 5) s, the hold U(5, 12) s, the straight flight before
    U(1, 3) s (and 2 s after).

    Args:
        seed: the seed.
        dt: the sampling period, s.

    Returns:
        The motion at the pilot's head.
    """
    rng = motion_rng("coordinated_turn", seed)
    speed = uniform(rng, 50.0, 130.0)
    bank = math.radians(uniform(rng, 15.0, 45.0)) * (1.0 if rng.random() < 0.5 else -1.0)
    roll_in, roll_out = uniform(rng, 2.0, 5.0), uniform(rng, 2.0, 5.0)
    hold = uniform(rng, 5.0, 12.0)
    before = uniform(rng, 1.0, 3.0)
    t = _samples(before + roll_in + hold + roll_out + 2.0, dt)
    # a positive roll (about x forward, y left, z up) lowers the right wing: a right turn, in which
    # the heading turns clockwise seen from above (psi_dot < 0 about z up)
    phi = bank * (smoothstep(t, before, roll_in) - smoothstep(t, before + roll_in + hold, roll_out))
    phi_dot = np.gradient(phi, dt)
    turn_rate = -STANDARD_GRAVITY * np.tan(phi) / speed
    # omega = (phi_dot, 0, 0) + R_x(phi)^T (0, 0, psi_dot): the body's y axis tilts down on the right
    omega = np.stack([phi_dot, turn_rate * np.sin(phi), turn_rate * np.cos(phi)], axis=1)
    force = np.zeros_like(omega)
    force[:, 2] = STANDARD_GRAVITY / np.cos(phi)
    force = at_head(force, omega, PILOT_HEAD, dt)
    return motion(
        "coordinated_turn",
        seed,
        dt,
        force,
        omega,
        airspeed=speed,
        bank=bank,
        roll_in=roll_in,
        hold=hold,
        roll_out=roll_out,
        before=before,
    )


def takeoff_roll(seed: int, dt: float = 0.01) -> VehicleMotion:
    """A light aircraft's take-off: the roll, the rotation, the lift-off and the start of the climb.

    Along the runway ``V_dot = a0 (1 - (V / V_max)²)`` (thrust less drag), with the runway's
    roughness on the vertical specific force and on the roll and pitch rates (white noise through a
    second-order Butterworth filter of 3 Hz, smooth enough for the rates' derivatives); the brakes are released 1 s into the run and the thrust builds up over 0.5 s.  At V_R the aircraft
    pitches up to the climb attitude theta over 2.5 s; lift-off comes 1.5 s later, and the flight
    path's angle gamma then rises to theta - 4 degrees over 3 s (``f_z`` rises with the pull-up's
    ``V gamma_dot``); the run ends 5 s after lift-off.

    Drawn: the acceleration at rest a0 U(2.5, 4) m/s², V_R U(26, 40) m/s, the climb attitude theta
    U(8, 12) degrees, the roughness's RMS U(0.2, 0.6) m/s² (vertical) and U(0.01, 0.03) rad/s.

    Args:
        seed: the seed.
        dt: the sampling period, s.

    Returns:
        The motion at the pilot's head.
    """
    signal = _scipy_signal()
    rng = motion_rng("takeoff_roll", seed)
    a0 = uniform(rng, 2.5, 4.0)
    v_rotate = uniform(rng, 26.0, 40.0)
    theta_climb = math.radians(uniform(rng, 8.0, 12.0))
    rough_f, rough_w = uniform(rng, 0.2, 0.6), uniform(rng, 0.01, 0.03)
    v_max = 1.6 * v_rotate
    release, spool = 1.0, 0.5
    # V_dot = a0 s(t) (1 - (V / v_max)²), s the thrust's smooth step from the brakes' release over
    # `spool` seconds, gives V = v_max tanh(a0 run / v_max), run the integral of s
    run_rotate = v_max / a0 * math.atanh(v_rotate / v_max)
    t_rotate = release + run_rotate + spool / 2.0
    t_lift = t_rotate + 4.0
    t = _samples(t_lift + 5.0, dt)
    tau = np.clip(t - release, 0.0, None)
    run = np.where(tau < spool, tau / 2.0 - spool / (2.0 * math.pi) * np.sin(math.pi * tau / spool), tau - spool / 2.0)
    speed = v_max * np.tanh(a0 * run / v_max)
    along = a0 * smoothstep(t, release, spool) * (1.0 - (speed / v_max) ** 2)
    theta = theta_climb * smoothstep(t, t_rotate, 2.5)
    gamma = max(theta_climb - math.radians(4.0), 0.0) * smoothstep(t, t_lift, 3.0)
    gamma_dot = np.gradient(gamma, dt)
    # the earth-fixed specific force (x along the runway, z up), then in the body pitched nose-up
    fx_e = along * np.cos(gamma) - speed * gamma_dot * np.sin(gamma)
    fz_e = along * np.sin(gamma) + speed * gamma_dot * np.cos(gamma) + STANDARD_GRAVITY
    force = np.stack(
        [np.cos(theta) * fx_e + np.sin(theta) * fz_e, np.zeros_like(t), -np.sin(theta) * fx_e + np.cos(theta) * fz_e],
        axis=1,
    )
    # nose-up pitch turns about -y (y left)
    omega = np.zeros_like(force)
    omega[:, 1] = -np.gradient(theta, dt)
    # the runway's roughness while the wheels roll, growing with the speed
    on_ground = (t < t_lift) * np.clip(speed / v_rotate, 0.0, 1.0)
    b, a = signal.butter(2, 3.0, fs=1.0 / dt)
    noise = signal.lfilter(b, a, rng.standard_normal((len(t), 3)), axis=0)
    noise /= max(float(noise.std()), 1e-12)
    force[:, 2] += rough_f * on_ground * noise[:, 0]
    omega[:, 0] += rough_w * on_ground * noise[:, 1]
    omega[:, 1] += rough_w * on_ground * noise[:, 2]
    force = at_head(force, omega, PILOT_HEAD, dt)
    return motion(
        "takeoff_roll",
        seed,
        dt,
        force,
        omega,
        acceleration=a0,
        rotation_speed=v_rotate,
        climb_attitude=theta_climb,
        roughness_force=rough_f,
        roughness_rate=rough_w,
    )


def dryden_gusts(
    rng: np.random.Generator, n: int, dt: float, airspeed: float, altitude: float, wind20: float, span: float
) -> np.ndarray:
    """Gusts of the Dryden model of MIL-F-8785C at low altitude (below 1000 ft).

    Scales ``L_w = h``, ``L_u = L_v = h / (0.177 + 0.000823 h)^1.2`` (h in ft); intensities
    ``sigma_w = 0.1 W20``, ``sigma_u = sigma_v = sigma_w / (0.177 + 0.000823 h)^0.4`` (W20 the wind
    speed at 20 ft).  The forms ``H_u = sigma_u sqrt(2 L_u / (pi V)) / (1 + L_u s / V)``,
    ``H_v,w = sigma sqrt(L / (pi V)) (1 + sqrt(3) L s / V) / (1 + L s / V)²``, the rotary gusts
    ``p = sigma_w sqrt(0.8 / V) (pi / 4b)^(1/6) / (L_w^(1/3) (1 + 4 b s / (pi V)))``,
    ``q = (s / V) / (1 + 4 b s / (pi V)) w`` and ``r = -(s / V) / (1 + 3 b s / (pi V)) v``; each
    form is driven by white noise of two-sided spectral density pi (samples of variance pi / dt),
    so that the output's variance is sigma².

    Args:
        rng: the random stream.
        n: the number of samples.
        dt: the sampling period, s.
        airspeed: V, m/s.
        altitude: h, m (clipped to 10..300 m, the model's low-altitude range).
        wind20: W20, m/s.
        span: the wing span b, m.

    Returns:
        (n, 6): the gust velocities u, v, w (m/s) and rates p, q, r (rad/s) in the aircraft's
        axes of MIL-F-8785C (x forward, y right, z down).
    """
    h_ft = min(max(altitude, 10.0), 300.0) / _FEET
    denominator = 0.177 + 0.000823 * h_ft
    length_w = h_ft * _FEET
    length_uv = h_ft / denominator**1.2 * _FEET
    sigma_w = 0.1 * wind20
    sigma_uv = sigma_w / denominator**0.4
    v = airspeed
    white = rng.standard_normal((n, 4)) * math.sqrt(math.pi / dt)

    def run(num, den, u):
        signal = _scipy_signal()
        bd, ad = signal.bilinear(num, den, fs=1.0 / dt)
        return signal.lfilter(bd, ad, u)

    tu = length_uv / v
    u_g = run([sigma_uv * math.sqrt(2.0 * length_uv / (math.pi * v))], [tu, 1.0], white[:, 0])

    def lateral(sigma, length, u):
        tl = length / v
        gain = sigma * math.sqrt(length / (math.pi * v))
        return run([gain * math.sqrt(3.0) * tl, gain], [tl * tl, 2.0 * tl, 1.0], u)

    v_g = lateral(sigma_uv, length_uv, white[:, 1])
    w_g = lateral(sigma_w, length_w, white[:, 2])
    tp = 4.0 * span / (math.pi * v)
    p_gain = sigma_w * math.sqrt(0.8 / v) * (math.pi / (4.0 * span)) ** (1.0 / 6.0) / length_w ** (1.0 / 3.0)
    p_g = run([p_gain], [tp, 1.0], white[:, 3])
    q_g = run([1.0 / v, 0.0], [tp, 1.0], w_g)
    r_g = run([-1.0 / v, 0.0], [3.0 * span / (math.pi * v), 1.0], v_g)
    return np.stack([u_g, v_g, w_g, p_g, q_g, r_g], axis=1)


def _ride(gain: float, gust: np.ndarray, dt: float) -> np.ndarray:
    """The acceleration ``K (gust - v)``, ``v' = K (gust - v)``, of a body riding a gust: the gust
    through ``K s / (s + K)`` (bilinear), from rest relative to the air."""
    signal = _scipy_signal()
    b, a = signal.bilinear([gain, 0.0], [1.0, gain], fs=1.0 / dt)
    return signal.lfilter(b, a, gust)


def turbulence(seed: int, dt: float = 0.01) -> VehicleMotion:
    """Steady level flight of :data:`AIRCRAFT` through Dryden turbulence (see :func:`dryden_gusts`).

    The gusts' loads at the centre of mass (our axes, y left, z up): an upward gust ``w`` adds the
    lift ``q S C_L_alpha (w - w_a) / V``, ``w_a`` the aircraft's own vertical velocity, which the
    lift accelerates (the plunge mode, of time constant ``m V / (q S C_L_alpha)``, about 0.4 s:
    the aircraft rides the gusts' slow part); a gust from the right moves the air to the left (v
    in our axes) and pushes the aircraft with it, the side force ``q S |C_Y_beta| (v - v_a) / V``
    likewise; a tailwind ``u`` takes off the lift ``2 g u / V`` and the drag ``rho V S C_D u``.

    Drawn: the airspeed U(45, 65) m/s, the altitude U(100, 300) m, the wind at 20 ft W20
    U(8, 15) kt (up to MIL-F-8785C's light turbulence, 15 kt), and the gusts; 20 s of flight.

    Args:
        seed: the seed.
        dt: the sampling period, s.

    Returns:
        The motion at the pilot's head.
    """
    signal = _scipy_signal()
    rng = motion_rng("turbulence", seed)
    speed = uniform(rng, 45.0, 65.0)
    altitude = uniform(rng, 100.0, 300.0)
    wind20 = uniform(rng, 8.0, 15.0) * _KNOTS
    t = _samples(20.0, dt)
    # a 10 s run-in first, cut off at the end, so that the filters start in their stationary state
    run_in = int(round(10.0 / dt))
    gusts = dryden_gusts(rng, len(t) + run_in, dt, speed, altitude, wind20, AIRCRAFT.span)
    # MIL-F-8785C's axes (y right, z down) to ours (y left, z up)
    u_g, v_g, w_g = gusts[:, 0], -gusts[:, 1], -gusts[:, 2]
    omega = np.stack([gusts[:, 3], -gusts[:, 4], -gusts[:, 5]], axis=1)
    c = AIRCRAFT
    q_s = 0.5 * AIR_DENSITY * speed * c.wing_area / c.mass  # (dynamic pressure x area / mass) / V
    # the aircraft plunges and side-slips with the gusts: ``a = K (gust - velocity)`` and
    # ``velocity' = a`` make the load ``K s / (s + K)`` of the gust, a first-order high-pass
    heave, sway = _ride(q_s * c.lift_slope, w_g, dt), _ride(q_s * c.side_force_slope, v_g, dt)
    force = np.stack(
        [
            AIR_DENSITY * speed * c.wing_area * c.drag_coefficient / c.mass * u_g,
            sway,
            STANDARD_GRAVITY + heave - 2.0 * STANDARD_GRAVITY / speed * u_g,
        ],
        axis=1,
    )[run_in:]
    # the aircraft turns with the air mass through its rotary damping, a lag of ROTARY_LAG seconds
    # (which also keeps omega_dot, and the specific force at the head, free of the gusts' white noise)
    b, a = signal.bilinear([1.0], [ROTARY_LAG, 1.0], fs=1.0 / dt)
    omega = signal.lfilter(b, a, omega, axis=0)[run_in:]
    force = at_head(force, omega, PILOT_HEAD, dt)
    return motion("turbulence", seed, dt, force, omega, airspeed=speed, altitude=altitude, wind20=wind20)
