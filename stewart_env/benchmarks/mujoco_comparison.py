"""MuJoCo beside the kernels on the same mechanism (``stewart-env bench --mujoco``, the ``mujoco``
extra): forward and inverse dynamics, a control step for one platform and a batch, the resets."""

from __future__ import annotations

import os
import time

import numpy as np

import stewart_env as se
from stewart_env.benchmarks.measurements import _batch_state, _per_call
from stewart_env.progress import on_terminal, progress


def bench_mujoco(
    params, n_batch: int = 1024, repeats: int = 10, calls: int = 1000, substeps: int = 10, dt: float = 1e-3
) -> dict:
    """MuJoCo and stewart-env side by side on the same mechanism.

    The mechanism is stewart_env.mujoco's twin of ``params``, the platform at home at rest under
    its holding forces.  Seconds per call:

    * ``forward_mujoco`` (``mujoco.mj_forward``), ``forward_api`` (``Dynamics.forward``, N = 1,
      with its checks), ``forward_workspace`` (``Workspace.forward``, N = 1);
    * ``inverse_mujoco`` (``mujoco.mj_inverse``), ``inverse_api`` (``Dynamics.inverse``),
      ``inverse_workspace`` (``Workspace.inverse``), and ``mass_and_bias_workspace``
      (``Workspace.mass_and_bias``, which has no counterpart in MuJoCo's task-space terms);
    * one control step of ``substeps`` RK4 steps of ``dt``, one platform: ``step_mujoco``
      (``mujoco.mj_step``), ``step_plant`` (:class:`stewart_env.mujoco.MujocoPlant`),
      ``step_env`` (``StewartPlatform-v1`` through ``gymnasium.make``, the set-point task from its
      fixed start held by its holding forces), ``step_env_mujoco`` (the same env with
      ``model="mujoco"``),
      ``step_rollout`` (``rollout_inplace``, N = 1), ``step_workspace`` (``Workspace.step``),
      ``step_env_pose_electric`` (the env in the pose mode, ``"ik"`` law, on the electric actuator:
      the inner loop and the drive at every RK4 step; None for a platform without an electric set);
    * the same step for ``n_batch`` platforms, per platform: ``batch_mujoco`` (``mujoco.rollout``
      on every core), ``batch_vector_env`` (the native vector env), ``batch_vector_env_pose_electric``
      (the same in the pose mode on the electric actuator, or None), ``batch_rollout``
      (``rollout_inplace``, N = ``n_batch``);
    * ``reset_randomized`` and ``reset_nominal``: ``reset()`` of the vector env of ``n_batch``
      rows, per row, with :data:`~stewart_env.benchmarks.envs.RESET_RANDOMIZATION` and without.

    Each figure is the best of ``repeats`` loops (``calls`` calls for the single-platform figures),
    the loops of a group taking turns.  The single-platform figures are CPU time of this process
    per call (``time.process_time``), the batch figures and the resets wall-clock time; the vector
    env's steps start from its reset (the resets are timed apart).

    Args:
        params: the platform.
        n_batch: the platforms of the batch figures.
        repeats: the loops timed per figure, of which the best counts.
        calls: the calls per loop of the single-platform figures.
        substeps: the RK4 steps of a control step.
        dt: the RK4 step, s.

    Returns:
        The figures above by name (s), with ``substeps``, ``dt`` and ``n_batch``.

    Raises:
        MissingExtra: MuJoCo is not installed (the ``mujoco`` extra).
    """
    import gymnasium as gym

    from stewart_env.benchmarks.envs import RESET_RANDOMIZATION, bench_reset, held_env
    from stewart_env.integrate import rollout_inplace
    from stewart_env.mujoco import MujocoPlant, model_and_data, require_mujoco
    from stewart_env.mujoco.library import require_rollout
    from stewart_env.registration import ENV_ID

    mujoco, mujoco_rollout = require_mujoco(), require_rollout()

    model = se.make_dynamics("improved", params)
    t, R = params.home_position, se.rpy_to_matrix(params.home_rpy)
    z = np.zeros(3)
    F = model.inverse(t, R, z, z, z, z)
    out = {"n_batch": n_batch, "substeps": substeps, "dt": dt}
    # One platform: the process's CPU time, which other work on a shared machine inflates far less
    # than the wall clock; every call compared runs on this thread.
    cpu = time.process_time
    bar = progress(total=8, desc="bench --mujoco", disable=not on_terminal())

    m, d = model_and_data(params, t, R, z, z, F, timestep=dt)
    start = mujoco.MjData(m)
    mujoco.mj_copyData(start, m, d)
    ws = model.workspace(1)
    ws.set_state(t, R, z, z)
    ws.leg_forces[0] = F
    out.update(
        _per_call(
            {
                "forward_mujoco": lambda: mujoco.mj_forward(m, d),
                "forward_api": lambda: model.forward(t, R, z, z, F),
                "forward_workspace": ws.forward,
            },
            calls,
            repeats,
            cpu,
        )
    )
    ws.acceleration[0] = 0.0  # Workspace.inverse then writes the holding forces back into leg_forces
    out.update(
        _per_call(
            {
                "inverse_mujoco": lambda: mujoco.mj_inverse(m, d),  # of mj_forward's qacc
                "inverse_api": lambda: model.inverse(t, R, z, z, z, z),
                "inverse_workspace": ws.inverse,
                "mass_and_bias_workspace": ws.mass_and_bias,
            },
            calls,
            repeats,
            cpu,
        )
    )
    bar.update()

    step_calls = max(1, calls // substeps)
    plant = MujocoPlant(params, dt)
    plant_state = [t[None].copy(), R[None].copy(), np.zeros((1, 3)), np.zeros((1, 3))]
    state = [x.copy() for x in plant_state]
    forces, wrench = F[None].copy(), np.zeros((1, 6))
    start_state = [x.copy() for x in plant_state]
    env_kwargs = dict(task_options={"randomize": False}, platform=params, control_dt=dt * substeps, physics_dt=dt)
    env, env_action = held_env(**env_kwargs)
    mj_env, mj_env_action = held_env(model="mujoco", **env_kwargs)
    # the pose mode on the electric actuator, where the platform has an electric set
    actuated_kwargs = dict(env_kwargs, action_mode="pose", actuator="electric")
    actuated = params.actuators.electric is not None
    pose_env, pose_action = held_env(**actuated_kwargs) if actuated else (None, None)

    def back_to_start():
        # the platform at rest under its holding forces is an unstable equilibrium: the rounding
        # error grows about 1e5-fold per simulated second, and a few seconds end it in a singular
        # pose, where a step stops early; each loop of step_calls steps starts at rest again
        mujoco.mj_copyData(d, m, start)
        for x0, *xs in zip(start_state, plant_state, state):
            for x in xs:
                x[...] = x0
        ws.set_state(t, R, z, z)
        env.reset(seed=0)
        mj_env.reset(seed=0)
        if actuated:
            pose_env.reset(seed=0)

    out.update(
        _per_call(
            {
                "step_mujoco": lambda: mujoco.mj_step(m, d, nstep=substeps),
                "step_plant": lambda: plant.step_inplace(*plant_state, forces, wrench, dt, substeps),
                "step_rollout": lambda: rollout_inplace(model, *state, forces, wrench, dt, substeps),
                "step_workspace": lambda: ws.step(dt, substeps),
                "step_env": lambda: env.step(env_action),
                "step_env_mujoco": lambda: mj_env.step(mj_env_action),
                **({"step_env_pose_electric": lambda: pose_env.step(pose_action)} if actuated else {}),
            },
            step_calls,
            repeats,
            cpu,
            reset=back_to_start,
        )
    )
    env.close()
    mj_env.close()
    out.setdefault("step_env_pose_electric", None)
    if actuated:
        pose_env.close()
    bar.update()

    # the batch: MuJoCo's threaded rollout of n_batch platforms from the same state, open loop
    nthread = os.cpu_count() or 1
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    initial = np.empty(mujoco.mj_stateSize(m, spec))
    mujoco.mj_getState(m, start, initial, spec)
    initial = np.tile(initial, (n_batch, 1))
    control = np.tile(F, (n_batch, substeps, 1))
    states = np.empty((n_batch, substeps, initial.shape[1]))
    datas = [mujoco.MjData(m) for _ in range(nthread)]
    bt, bR, bv, bw, bF = _batch_state(model, n_batch, np.random.default_rng(0))
    bW = np.zeros((n_batch, 6))
    venv = gym.make_vec(ENV_ID, num_envs=n_batch, vectorization_mode="vector_entry_point", **env_kwargs)
    venv_actions = np.tile(env_action, (n_batch, 1))
    venv.reset(seed=0)
    pose_venv = None
    if actuated:
        pose_venv = gym.make_vec(ENV_ID, num_envs=n_batch, vectorization_mode="vector_entry_point", **actuated_kwargs)
        pose_venv_actions = np.tile(pose_action, (n_batch, 1))
        pose_venv.reset(seed=0)

    def reset_vector_envs():
        venv.reset(seed=0)
        if pose_venv is not None:
            pose_venv.reset(seed=0)

    with mujoco_rollout.Rollout(nthread=nthread) as pool:
        batch = _per_call(
            {
                "batch_mujoco": lambda: pool.rollout(m, datas, initial, control, state=states),
                "batch_rollout": lambda: rollout_inplace(model, bt, bR, bv, bw, bF, bW, dt, substeps),
                "batch_vector_env": lambda: venv.step(venv_actions),
                **({"batch_vector_env_pose_electric": lambda: pose_venv.step(pose_venv_actions)} if actuated else {}),
            },
            1,
            repeats,
            reset=reset_vector_envs,
        )
    venv.close()
    if pose_venv is not None:
        pose_venv.close()
    batch.setdefault("batch_vector_env_pose_electric", None)
    out.update({name: None if seconds is None else seconds / n_batch for name, seconds in batch.items()})
    bar.update(2)

    bar.update(3)
    out["reset_randomized"] = bench_reset(n_batch, RESET_RANDOMIZATION, max(1, repeats // 2), platform=params)
    out["reset_nominal"] = bench_reset(n_batch, None, max(1, repeats // 2), platform=params)
    bar.update()
    bar.close()
    return out
