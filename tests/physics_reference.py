"""Reference quantities written independently of the kernels, for the physics tests.

Energies and potentials of all 13 bodies (platform, six lower and six upper legs) straight from
their definitions, and random platform states near the home pose.
"""

import numpy as np

import stewart_env as se


def random_state(params, rng, speed=0.2):
    """A pose near home with random velocities: (t, R, v, w) in {B}."""
    t = params.home_position + rng.uniform(-0.05, 0.05, 3)
    R = se.rpy_to_matrix(params.home_rpy + rng.uniform(-0.15, 0.15, 3))
    v = rng.normal(scale=speed, size=3)
    w = rng.normal(scale=2 * speed, size=3)
    return t, R, v, w


def leg_frames(params, t, R):
    """U-joint leg frames from their definition: e along the leg, y = unit(k x e), z = e x y."""
    S = t + (R @ params.platform_joints.T).T - params.base_joints
    L = np.linalg.norm(S, axis=1)
    e = S / L[:, None]
    y = np.cross(params.hooke_axes, e)
    y /= np.linalg.norm(y, axis=1)[:, None]
    z = np.cross(e, y)
    return L, np.stack([e, y, z], axis=2)


def body_coms(params, t, R):
    """CoM positions in {B}: platform (3,), lower legs (6,3), upper legs (6,3)."""
    L, T = leg_frames(params, t, R)
    r_d = np.stack([T[i] @ params.lower_leg[i].com for i in range(6)])
    r_u = np.stack([L[i] * T[i][:, 0] + T[i] @ params.upper_leg[i].com for i in range(6)])
    return t + R @ params.platform.com, params.base_joints + r_d, params.base_joints + r_u


def potential_energy(params, t, R):
    """Gravitational potential energy of all 13 bodies, J."""
    com_p, com_d, com_u = body_coms(params, t, R)
    g = params.gravity
    V = -params.platform.mass * g @ com_p
    for i in range(6):
        V -= params.lower_leg[i].mass * g @ com_d[i] + params.upper_leg[i].mass * g @ com_u[i]
    return V


def kinetic_energy(params, t, R, v, w):
    """Kinetic energy of all 13 bodies, J; leg angular velocities (spin included) from the
    leg kinematics, which the finite-difference tests check on their own."""
    k = se.leg_kinematics(params, t, R, v, w)
    rho = R @ params.platform.com
    v_c = v + np.cross(w, rho)
    I_p = R @ params.platform.inertia @ R.T
    T_kin = 0.5 * params.platform.mass * v_c @ v_c + 0.5 * w @ I_p @ w
    for i in range(6):
        Ti, wl, e, L = k.frames[i], k.omega[i], k.units[i], k.lengths[i]
        r_d = Ti @ params.lower_leg[i].com
        r_u = L * e + Ti @ params.upper_leg[i].com
        for body, vel in (
            (params.lower_leg[i], np.cross(wl, r_d)),
            (params.upper_leg[i], k.rates[i] * e + np.cross(wl, r_u)),
        ):
            I_c = Ti @ body.inertia @ Ti.T
            T_kin += 0.5 * body.mass * vel @ vel + 0.5 * wl @ I_c @ wl
    return T_kin


def dissipated_power(params, t, R, v, w):
    """Power lost in the joints' viscous friction, W."""
    k = se.leg_kinematics(params, t, R, v, w)
    d = params.damping
    rel = k.omega - w
    return d.universal * np.sum(k.omega**2) + d.prismatic * np.sum(k.rates**2) + d.spherical * np.sum(rel**2)


def rotvec_matrix(phi):
    """exp([phi]x), Rodrigues."""
    a = np.linalg.norm(phi)
    if a == 0:
        return np.eye(3)
    k = phi / a
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(a) * K + (1 - np.cos(a)) * K @ K


def left_jacobian(phi):
    """dexp: omega = Jl(phi) dphi/dt for R = exp([phi]x) R0, omega in {B}."""
    a = np.linalg.norm(phi)
    K = np.array([[0, -phi[2], phi[1]], [phi[2], 0, -phi[0]], [-phi[1], phi[0], 0]])
    if a < 1e-8:
        return np.eye(3) + 0.5 * K
    return np.eye(3) + (1 - np.cos(a)) / a**2 * K + (a - np.sin(a)) / a**3 * K @ K
