"""Speed of the environments: single-env steps/s through ``gymnasium.make`` and vector platform-steps/s.

``stewart-env bench --env`` prints what these measure.
"""

from __future__ import annotations

import time

import gymnasium as gym
import numpy as np

from stewart_env.envs.stewart_platform import holding_action
from stewart_env.registration import ENV_ID  # importing it registers the environment

__all__ = ["RESET_RANDOMIZATION", "bench_env", "bench_reset", "bench_resets_in_steps"]

#: The domain randomisation whose reset :func:`bench_reset` times: every body's mass and inertia within +-20 %.
RESET_RANDOMIZATION = {"mass": (0.8, 1.2), "inertia": (0.8, 1.2)}


def _timed(step, seconds: float, batch: int = 64) -> tuple[int, float, float]:
    """Call ``step`` in batches until ``seconds`` have passed; (calls, wall s, process CPU s)."""
    calls, start, cpu = 0, time.perf_counter(), time.process_time()
    while True:
        for _ in range(batch):
            step()
        calls += batch
        elapsed = time.perf_counter() - start
        if elapsed >= seconds:
            return calls, elapsed, time.process_time() - cpu


def held_env(**kwargs) -> tuple[gym.Env, np.ndarray]:
    """``gymnasium.make("StewartPlatform-v1", **kwargs)`` reset with seed 0, and the float32 action
    that holds the platform at that start pose (in the pose mode, the start pose commanded).  Held so, the open-loop platform drifts off slowly:
    an episode runs for hundreds of steps, so a timing loop times steps, not resets.

    Args:
        **kwargs: keyword arguments of the environment.
    """
    env = gym.make(ENV_ID, **kwargs)
    env.reset(seed=0)
    state = env.unwrapped.state
    if kwargs.get("action_mode") == "pose":
        # the pose mode's inner loop holds the start pose commanded
        action = env.unwrapped._core.actuation.pose_command(state.position, state.rotation)
        return env, action.astype(np.float32)
    return env, holding_action(env, state.position, state.rotation).astype(np.float32)


def bench_env(n_vector: int = 1024, seconds: float = 5.0, **kwargs) -> dict:
    """Measure both environments with default settings (improved model, control_dt 0.01 s,
    physics_dt 0.001 s: 10 RK4 substeps per step) or the given keyword arguments of the
    environment.  The setpoint task starts at its fixed pose (``task_options={"randomize":
    False}``, overridable) and the action holds the platform there, so that episodes are long;
    the physics and the per-step work are those of the default task.

    Returns a dict: single_steps_per_s (``gymnasium.make`` with its default wrappers: passive
    checker, order enforcing, time limit), vector_platform_steps_per_s (N x steps/s of
    ``gymnasium.make_vec(..., vectorization_mode="vector_entry_point")`` at N = ``n_vector``),
    vector_steps_per_s, the episode resets counted in each run, and the settings; all per second
    of wall-clock time, and the two rates also per second of this process's CPU time
    (``*_per_cpu_s``), which other load on the machine does not lower (the vector env uses every
    core, so on an idle machine its wall-clock rate approaches cores x its CPU-time rate).  A
    short warm-up (which includes any first compilation) is not timed.

    Args:
        n_vector: the platforms N of the vector environment; 0 measures the single env only (no
            vector_* keys).
        seconds: the wall-clock time each environment is timed for, s.
        **kwargs: keyword arguments of the environment (over the held set-point task's).
    """
    kwargs = {"task_options": {"randomize": False}, **kwargs}
    env, action = held_env(**kwargs)
    resets = [0]

    def single_step():
        _, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            env.reset()
            resets[0] += 1

    _timed(single_step, 0.2)
    resets[0] = 0
    single_calls, single_s, single_cpu = _timed(single_step, seconds)
    single_resets = resets[0]
    env.close()

    u = env.unwrapped
    out = {
        "single_steps_per_s": single_calls / single_s,
        "single_steps_per_cpu_s": single_calls / single_cpu,
        "single_resets": single_resets,
        "n_vector": n_vector,
        "control_dt": u.dt,
        "model": u.model.name,
        "task": u.task.name,
    }
    if not n_vector:
        return out
    venv = gym.make_vec(ENV_ID, num_envs=n_vector, vectorization_mode="vector_entry_point", **kwargs)
    actions = np.tile(action, (n_vector, 1))
    venv.reset(seed=0)
    vector_resets = [0]

    def vector_step():
        _, _, terminated, truncated, _ = venv.step(actions)
        vector_resets[0] += int(np.count_nonzero(terminated | truncated))

    _timed(vector_step, 0.5, batch=2)
    vector_resets[0] = 0
    vector_calls, vector_s, vector_cpu = _timed(vector_step, seconds, batch=2)
    venv.close()
    return {
        **out,
        "vector_platform_steps_per_s": vector_calls * n_vector / vector_s,
        "vector_platform_steps_per_cpu_s": vector_calls * n_vector / vector_cpu,
        "vector_steps_per_s": vector_calls / vector_s,
        "vector_resets": vector_resets[0],
    }


def bench_reset(n: int = 1024, randomization: dict | None = RESET_RANDOMIZATION, repeats: int = 3, **kwargs) -> float:
    """Seconds per row of ``reset()`` of the native vector env of ``n`` rows (every row starts a new
    episode, so with ``randomization`` every row draws and applies new parameters); the best of
    ``repeats`` resets after one untimed reset (which includes any first compilation).

    Args:
        n: the rows of the vector environment.
        randomization: the environment's ``randomization`` argument (None: no randomization).
        repeats: the timed resets, of which the fastest counts.
        **kwargs: further keyword arguments of the environment.
    """
    venv = gym.make_vec(
        ENV_ID, num_envs=n, vectorization_mode="vector_entry_point", randomization=randomization, **kwargs
    )
    venv.reset(seed=0)
    best = np.inf
    for seed in range(1, repeats + 1):
        start = time.perf_counter()
        venv.reset(seed=seed)
        best = min(best, time.perf_counter() - start)
    venv.close()
    return best / n


def bench_resets_in_steps(n: int = 1024, steps: int = 40, repeats: int = 3, seed: int = 0, **kwargs) -> dict:
    """The native vector env's wall-clock time per platform-step under uniformly random actions (a
    policy that still loses the platform, as at the start of training: a row resets every ten or
    so steps), nominal and with :data:`RESET_RANDOMIZATION`, beside its step alone: the setpoint
    task at its fixed start pose under the action that holds it there, no time limit, so that no
    row resets (``resets_step`` counts any that do; it starts each run afresh, as held the platform
    drifts out of its limits in some 170 steps).  The three runs are interleaved ``repeats``
    times and each figure is the best of its runs (other load on the machine falls on all alike);
    each run of ``steps`` steps follows ``steps // 2`` untimed ones, so the resets are at their
    steady rate.

    Args:
        n: rows of the vector env.
        steps: timed steps of each run, 1 to 100.
        repeats: interleaved runs of each of the three.
        seed: the seed of the resets and of the random actions.
        **kwargs: keyword arguments of the environment.

    Returns:
        A dict: step_s (the step alone), reset_nominal_s and reset_randomized_s, seconds per
        platform-step; reset_nominal_ratio and reset_randomized_ratio, each over step_s; the
        resets per platform-step of each run with resets (resets_nominal, resets_randomized);
        n and steps.

    Raises:
        ValueError: ``steps`` outside 1 to 100.
    """
    if not 1 <= steps <= 100:
        raise ValueError(f"steps: expected 1 to 100 (a held episode lasts some 170 steps), got {steps}")
    _, hold = held_env(task_options={"randomize": False}, **kwargs)
    envs = {
        "step": gym.make_vec(
            ENV_ID,
            num_envs=n,
            vectorization_mode="vector_entry_point",
            max_episode_steps=10**9,
            task_options={"randomize": False},
            **kwargs,
        ),
        "reset_nominal": gym.make_vec(ENV_ID, num_envs=n, vectorization_mode="vector_entry_point", **kwargs),
        "reset_randomized": gym.make_vec(
            ENV_ID, num_envs=n, vectorization_mode="vector_entry_point", randomization=RESET_RANDOMIZATION, **kwargs
        ),
    }
    rng = np.random.default_rng(seed)
    random_actions = [rng.uniform(-1.0, 1.0, (n, 6)).astype(np.float32) for _ in range(16)]
    held_actions = [np.tile(hold, (n, 1))]
    best = dict.fromkeys(envs, np.inf)
    resets = dict.fromkeys(envs, 0.0)
    for env in envs.values():
        env.reset(seed=seed)
    for _ in range(repeats):
        for name, env in envs.items():
            actions = held_actions if name == "step" else random_actions
            if name == "step":
                # held, the platform leaves its limits after some 170 steps: start each run afresh
                env.reset(seed=seed)
            for k in range(steps // 2):
                env.step(actions[k % len(actions)])
            count = 0
            start = time.perf_counter()
            for k in range(steps):
                _, _, terminated, truncated, _ = env.step(actions[k % len(actions)])
                count += int(np.count_nonzero(terminated | truncated))
            elapsed = (time.perf_counter() - start) / (steps * n)
            best[name] = min(best[name], elapsed)
            resets[name] = count / (steps * n)
    for env in envs.values():
        env.close()
    return {
        "n": n,
        "steps": steps,
        "step_s": best["step"],
        "reset_nominal_s": best["reset_nominal"],
        "reset_randomized_s": best["reset_randomized"],
        "reset_nominal_ratio": best["reset_nominal"] / best["step"],
        "reset_randomized_ratio": best["reset_randomized"] / best["step"],
        "resets_nominal": resets["reset_nominal"],
        "resets_randomized": resets["reset_randomized"],
        "resets_step": resets["step"],
    }
