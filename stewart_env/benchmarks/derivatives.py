"""The exact derivatives' cost (``stewart-env bench --derivatives``): the Jacobians of the forward
dynamics and of a control step beside the values, for one platform and a batch, and beside
MuJoCo's finite-difference derivatives of its step (``mujoco.mjd_transitionFD``) on the same
mechanism when the ``mujoco`` extra is installed."""

from __future__ import annotations

import time

import numpy as np

import stewart_env as se
from stewart_env import _core
from stewart_env.benchmarks.measurements import _batch_state, _per_call

__all__ = ["bench_derivatives", "derivatives_table"]


def bench_derivatives(
    params, n_batch: int = 256, repeats: int = 5, calls: int = 200, substeps: int = 10, dt: float = 1e-3
) -> dict:
    """The derivatives' cost beside the values', seconds per call.

    One platform at a moving state near home (CPU time of this process per call, best of
    ``repeats`` loops of ``calls`` calls taking turns), the compiled kernels called with their
    arrays made once:

    * ``forward`` (``forward_batch``, N = 1) and ``acceleration_jacobians``
      (``acceleration_jacobian_batch``: the acceleration and its 6x18 Jacobian);
    * ``step`` (``rollout_batch``: a control step of ``substeps`` RK4 steps of ``dt``) and
      ``step_jacobians`` (``step_jacobian_batch``: the step and its 12x18 Jacobian), and
      ``step_jacobians_api`` (:meth:`Dynamics.step_jacobians`, its argument checks included);
    * the same two step figures for ``n_batch`` platforms, per platform (wall clock):
      ``batch_step`` and ``batch_step_jacobians``;
    * with MuJoCo installed, on its twin of the platform (:mod:`stewart_env.mujoco`, timestep
      ``dt``, MuJoCo's default Euler integrator: ``mjd_transitionFD`` differentiates no RK4 step):
      ``mujoco_step`` (``mj_step`` of one step of ``dt``) and ``mujoco_transition_fd``
      (``mjd_transitionFD``: A and B of that one step by forward differences, MuJoCo's default),
      each times ``substeps`` to make a control step; otherwise None.

    Args:
        params: the platform.
        n_batch: the platforms of the batch figures.
        repeats: the loops timed per figure, of which the best counts.
        calls: the calls per loop of the single-platform figures.
        substeps: the RK4 steps of a control step.
        dt: the RK4 step, s.

    Returns:
        The figures above by name (s), with ``substeps``, ``dt`` and ``n_batch``.
    """
    model = se.make_dynamics("improved", params)
    rng = np.random.default_rng(0)
    t, R, v, w, F = (x[:1].copy() for x in _batch_state(model, 1, rng))
    W = np.zeros((1, 6))
    out = {"n_batch": n_batch, "substeps": substeps, "dt": dt}
    cpu = time.process_time
    acc, jac6, fin = np.empty((1, 6)), np.empty((1, 6, 18)), np.empty(1, dtype=bool)
    st = [np.empty((1, 3)), np.empty((1, 3, 3)), np.empty((1, 3)), np.empty((1, 3))]
    jac12 = np.empty((1, 12, 18))
    tr, Rr, vr, wr = (x.copy() for x in (t, R, v, w))
    p, flags = model.packed, model.flags

    def step():
        tr[...], Rr[...], vr[...], wr[...] = t, R, v, w
        _core.rollout_batch(p, flags, tr, Rr, vr, wr, F, W, dt, substeps)

    out.update(
        _per_call(
            {
                "forward": lambda: _core.forward_batch(p, flags, t, R, v, w, F, W, acc),
                "acceleration_jacobians": lambda: _core.acceleration_jacobian_batch(
                    p, flags, t, R, v, w, F, W, None, acc, jac6, fin
                ),
                "step": step,
                "step_jacobians": lambda: _core.step_jacobian_batch(
                    p, flags, t, R, v, w, F, W, None, dt, substeps, *st, jac12, fin
                ),
                "step_jacobians_api": lambda: model.step_jacobians(
                    t[0], R[0], v[0], w[0], F[0], dt * substeps, substeps
                ),
            },
            calls,
            repeats,
            cpu,
        )
    )

    bt, bR, bv, bw, bF = _batch_state(model, n_batch, rng)
    bW = np.zeros((n_batch, 6))
    bst = [np.empty((n_batch, 3)), np.empty((n_batch, 3, 3)), np.empty((n_batch, 3)), np.empty((n_batch, 3))]
    bjac, bfin = np.empty((n_batch, 12, 18)), np.empty(n_batch, dtype=bool)
    rolled = [x.copy() for x in (bt, bR, bv, bw)]

    def batch_step():
        for x, x0 in zip(rolled, (bt, bR, bv, bw)):
            x[...] = x0
        _core.rollout_batch(p, flags, *rolled, bF, bW, dt, substeps)

    batch = _per_call(
        {
            "batch_step": batch_step,
            "batch_step_jacobians": lambda: _core.step_jacobian_batch(
                p, flags, bt, bR, bv, bw, bF, bW, None, dt, substeps, *bst, bjac, bfin
            ),
        },
        1,
        repeats,
    )
    out.update({name: seconds / n_batch for name, seconds in batch.items()})

    out["mujoco_step"] = out["mujoco_transition_fd"] = None
    try:
        from stewart_env.mujoco import model_and_data, require_mujoco

        mujoco = require_mujoco()
    except ImportError:  # the extra is not installed (MissingExtra is an ImportError)
        return out
    m, d = model_and_data(params, t[0], R[0], v[0], w[0], F[0], timestep=dt)
    # mjd_transitionFD differentiates no RK4 step: MuJoCo's default integrator, semi-implicit Euler
    m.opt.integrator = mujoco.mjtIntegrator.mjINT_EULER
    start = mujoco.MjData(m)
    mujoco.mj_copyData(start, m, d)
    nx = 2 * m.nv + m.na
    A, B = np.empty((nx, nx)), np.empty((nx, m.nu))
    mujoco_calls = max(1, calls // substeps)
    figures = _per_call(
        {
            "mujoco_step": lambda: mujoco.mj_step(m, d),
            "mujoco_transition_fd": lambda: mujoco.mjd_transitionFD(m, d, 1e-6, 0, A, B, None, None),
        },
        mujoco_calls,
        repeats,
        cpu,
        reset=lambda: mujoco.mj_copyData(d, m, start),
    )
    out.update({name: seconds * substeps for name, seconds in figures.items()})
    return out


def derivatives_table(r: dict) -> str:
    """The markdown table of :func:`bench_derivatives`'s result: each value's cost beside its
    derivatives' and their ratio, and MuJoCo's beside them.

    Args:
        r: the result of :func:`bench_derivatives`.

    Returns:
        The table, one row a line.
    """
    us = 1e6
    control = f"{r['substeps']} x {r['dt'] * 1e3:g} ms"
    rows = [
        "| one platform | value | value and Jacobians | ratio |",
        "|---|---|---|---|",
        f"| forward dynamics (6x18) | {r['forward'] * us:.2f} us | {r['acceleration_jacobians'] * us:.2f} us "
        f"| {r['acceleration_jacobians'] / r['forward']:.1f} |",
        f"| control step, {control} RK4 (12x18) | {r['step'] * us:.1f} us | {r['step_jacobians'] * us:.1f} us "
        f"| {r['step_jacobians'] / r['step']:.1f} |",
        f"| the same, Dynamics.step_jacobians | | {r['step_jacobians_api'] * us:.1f} us | |",
        f"| the same, N={r['n_batch']}, per platform | {r['batch_step'] * us:.1f} us "
        f"| {r['batch_step_jacobians'] * us:.1f} us | {r['batch_step_jacobians'] / r['batch_step']:.1f} |",
    ]
    if r.get("mujoco_transition_fd") is not None:
        rows.append(
            f"| MuJoCo twin, {control} Euler: mj_step / mjd_transitionFD | {r['mujoco_step'] * us:.1f} us "
            f"| {r['mujoco_transition_fd'] * us:.1f} us | {r['mujoco_transition_fd'] / r['mujoco_step']:.1f} |"
        )
        rows.append(
            f"| stewart-env's Jacobians / MuJoCo's | | {r['step_jacobians'] / r['mujoco_transition_fd']:.3f} | |"
        )
    return "\n".join(rows)
