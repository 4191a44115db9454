"""The step info's success keys: ``is_success`` by the evaluation harness's criterion, and the
position and orientation errors it judges, in the single, vector and SB3 environments; the
observation, reward, termination and truncation the same bits as before they were added."""

from __future__ import annotations

import functools
import hashlib
import warnings

import gymnasium as gym
import numpy as np
import pytest

import stewart_env  # noqa: F401  (registers the ids)
from stewart_env.agents import PDPolicy, evaluate
from stewart_env.envs import StewartPlatformEnv, holding_action
from stewart_env.registration import ENV_IDS
from stewart_env.rotations import rotation_error
from stewart_env.tasks import TASKS, SetpointTask
from stewart_env.tasks.base import SuccessCriterion, error_norm

V0, V1 = ENV_IDS[0], ENV_IDS[1]
SUCCESS_KEYS = ("position_error", "orientation_error", "is_success")
PD_GC = functools.partial(PDPolicy, gravity_compensation=True)


def make(env_id: str = V1, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # Gymnasium: "-v0 is out of date"
        return gym.make(env_id, **kwargs)


def make_vec(num_envs: int, env_id: str = V1, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        return gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", **kwargs)


def true_errors(unwrapped) -> tuple[np.ndarray, np.ndarray]:
    """|e_p| (m) and |e_o| (rad) of every row now, as the evaluation harness measures them."""
    state, target = unwrapped.state, unwrapped.target
    position = np.atleast_2d(target.position - state.position)
    orientation = np.atleast_2d(rotation_error(target.rotation, state.rotation)[0])
    return np.linalg.norm(position, axis=1), np.linalg.norm(orientation, axis=1)


# -- the observation, reward, termination and truncation are those of before ------------------------


def single_digest(env_id: str, steps: int = 400, seed: int = 7, **kwargs) -> tuple[str, dict[str, int]]:
    """sha256 of a rollout's observations, rewards, terminated and truncated flags, across resets:
    the platform held where it is, with small noise one episode and large noise the next, so that
    episodes end both ways."""
    env = make(env_id, max_episode_steps=60, **kwargs)
    digest = hashlib.sha256()
    rng = np.random.default_rng(seed)
    obs, _ = env.reset(seed=seed)
    digest.update(obs.tobytes())
    episode, ends = 0, {"terminated": 0, "truncated": 0}
    for _ in range(steps):
        noise = 0.02 if episode % 2 == 0 else 0.5
        u = env.unwrapped
        action = holding_action(env, u.state.position, u.state.rotation) + noise * rng.standard_normal(6)
        obs, reward, terminated, truncated, _ = env.step(action.astype(np.float32))
        digest.update(obs.tobytes() + np.float64(reward).tobytes() + bytes([terminated, truncated]))
        if terminated or truncated:
            ends["terminated" if terminated else "truncated"] += 1
            episode += 1
            obs, _ = env.reset()
            digest.update(obs.tobytes())
    env.close()
    return digest.hexdigest(), ends


def vector_digest(env_id: str, steps: int = 150, seed: int = 3, **kwargs) -> str:
    """sha256 of a 3-row vector rollout's observations, rewards, terminated and truncated flags."""
    envs = make_vec(3, env_id, max_episode_steps=40, **kwargs)
    digest = hashlib.sha256()
    rng = np.random.default_rng(seed)
    obs, _ = envs.reset(seed=seed)
    digest.update(obs.tobytes())
    u = envs.unwrapped
    lo, hi = u.platform.limits.leg_force
    for _ in range(steps):
        z = np.zeros((3, 3))
        forces = u.model.inverse(u.state.position, u.state.rotation, z, z, z, z)
        action = (forces - 0.5 * (lo + hi)) / (0.5 * (hi - lo)) + 0.2 * rng.standard_normal((3, 6))
        obs, reward, terminated, truncated, _ = envs.step(action.astype(np.float32))
        digest.update(obs.tobytes() + reward.tobytes() + terminated.tobytes() + truncated.tobytes())
    envs.close()
    return digest.hexdigest()


# Computed before the success keys were added (commit 4979787): only the info gained keys.
SINGLE_DIGESTS = {
    (V1, "setpoint"): "1a7f8aca86718d00b240349ce29a292abdf95dd53db2ea1325f13c39c48100a5",
    (V0, "setpoint"): "1a7f8aca86718d00b240349ce29a292abdf95dd53db2ea1325f13c39c48100a5",
    (V1, "tracking"): "88a9654f3f6ca9552c1ff9c82e5b2e04c5cfd949fd08a32fc9f881811371207c",
    (V0, "tracking"): "e41371be7cff8447d688b5818c9279ae1ab60bee0f9b9eae22365685f760bc18",
}
VECTOR_DIGESTS = {
    (V1, "setpoint"): "a8ede7ed7ad2d82b9b6aade52baf7ebb08439f610f728531462da2653b0d6da1",
    (V0, "setpoint"): "a8ede7ed7ad2d82b9b6aade52baf7ebb08439f610f728531462da2653b0d6da1",
    (V1, "disturbance"): "eb61e77cb4cce8c32e80460561c9f95e0a06b940a7e568403132f1c964c5c9ad",
    (V0, "disturbance"): "5435ec07ca88c33df0e2435a792a0e3002df6d02201a5b2fb7750cbb177d1e6c",
}


@pytest.mark.parametrize("env_id,task", SINGLE_DIGESTS)
def test_a_single_rollout_is_the_same_bits_as_before(env_id, task):
    kwargs = {} if task == "setpoint" else {"task": task}  # setpoint: the default arguments
    digest, ends = single_digest(env_id, **kwargs)
    assert ends == {"terminated": 6, "truncated": 4}  # the rollout ends episodes both ways
    assert digest == SINGLE_DIGESTS[env_id, task]


@pytest.mark.parametrize("env_id,task", VECTOR_DIGESTS)
def test_a_vector_rollout_is_the_same_bits_as_before(env_id, task):
    kwargs = {} if task == "setpoint" else {"task": task}
    assert vector_digest(env_id, **kwargs) == VECTOR_DIGESTS[env_id, task]


# -- the keys and their values ----------------------------------------------------------------------


@pytest.mark.parametrize("task", TASKS)
def test_every_step_reports_the_errors_the_harness_measures(task):
    env = make(task=task)
    env.reset(seed=1)
    u = env.unwrapped
    for _ in range(30):
        _, _, terminated, _, info = env.step(holding_action(env, u.state.position, u.state.rotation))
        assert not terminated
        assert type(info["position_error"]) is np.float64 and type(info["orientation_error"]) is np.float64
        assert type(info["is_success"]) is np.bool_
        position, orientation = true_errors(env.unwrapped)
        # the same bits: the same errors, and norms summed in numpy's order
        assert info["position_error"] == position[0] and info["orientation_error"] == orientation[0]
    # metres and radians: inside the workspace (0.5 m across) and the angle limits (0.5 rad)
    assert 0.0 < info["position_error"] < 0.5 and 0.0 < info["orientation_error"] < 1.0


def test_is_success_at_every_step_is_the_criterion_on_the_episode_so_far():
    """At step k, is_success is the criterion's verdict on the episode cut at k: False until the
    platform has held the band over the latest tenth of the elapsed time, True at the end."""
    env = make(max_episode_steps=300)
    policy = PD_GC(env)
    obs, _ = env.reset(seed=0)
    position, orientation = true_errors(env.unwrapped)
    criterion = env.unwrapped.task.success_criterion
    assert criterion == SuccessCriterion()  # the harness's defaults: 2 mm, 0.01 rad, the final tenth
    inside, reported = [bool(criterion.inside(position[0], orientation[0]))], []
    truncated = False
    while not truncated:
        obs, _, terminated, truncated, info = env.step(policy.predict(obs)[0])
        assert not terminated
        inside.append(bool(criterion.inside(info["position_error"], info["orientation_error"])))
        reported.append(bool(info["is_success"]))
    time = env.unwrapped.dt * np.arange(len(inside))
    expected = [criterion.succeeded(time[: k + 1], np.array(inside[: k + 1]), False) for k in range(1, len(inside))]
    assert reported == expected
    assert not inside[0] and reported[0] is False and reported[-1] is True  # from off target to on it
    assert 0 < reported.index(True) < 150  # the PD law settles within 1.5 s


def test_a_terminated_step_is_no_success():
    env = make()
    env.reset(seed=0)
    for _ in range(500):
        _, _, terminated, _, info = env.step(np.full(6, -1.0, np.float32))  # pulls the platform down
        if terminated:
            break
    assert terminated and info["termination"] > 0 and info["is_success"] == np.False_


def test_the_criterion_is_the_task_s():
    """A task's own criterion decides: with the window the whole episode, the reset sample (off
    target) counts, and no set-point episode succeeds."""

    class WholeEpisode(SetpointTask):
        success_criterion = SuccessCriterion(final_window=1.0)

    default, whole = make(max_episode_steps=200), make(task=WholeEpisode, max_episode_steps=200)
    verdicts = []
    for env in (default, whole):
        policy = PD_GC(env)
        obs, _ = env.reset(seed=0)
        truncated = False
        while not truncated:
            obs, _, _, truncated, info = env.step(policy.predict(obs)[0])
        verdicts.append(bool(info["is_success"]))
    assert verdicts == [True, False]


def test_an_absurd_state_reports_finite_errors():
    env = make()
    env.reset(seed=0)
    u = env.unwrapped
    u.set_state(np.array([1e200, 0.0, 0.4]), u.state.rotation)  # |e_p|^2 overflows float64
    *_, info = env.step(np.zeros(6, np.float32))
    assert info["position_error"] == np.finfo(np.float64).max and not info["is_success"]


# -- the same verdict as the evaluation harness ---------------------------------------------------------


@pytest.mark.parametrize("episodes", [3, 6])  # a batch of a few rows goes row by row, a larger one at once
@pytest.mark.parametrize("task", ["setpoint", "disturbance", "hold"])
def test_the_vector_env_gives_the_harness_s_verdict_and_errors(task, episodes):
    steps, seed = 200, 11
    result = evaluate(PD_GC, {"task": task}, episodes=episodes, seed=seed, max_steps=steps, progress=False)
    envs = make_vec(episodes, task=task, max_episode_steps=steps)
    policy = PD_GC(envs)
    obs, _ = envs.reset(seed=seed)
    verdicts = [None] * episodes
    for k in range(steps):
        obs, _, terminated, truncated, infos = envs.step(policy.predict(obs)[0])
        for i, episode in enumerate(result.episodes):
            if verdicts[i] is None:
                norms = error_norm(episode.position_error[k + 1]), error_norm(episode.orientation_error[k + 1])
                assert (infos["position_error"][i], infos["orientation_error"][i]) == norms
                assert infos["_position_error"][i] and infos["_is_success"][i]
                if terminated[i] or truncated[i]:
                    verdicts[i] = bool(infos["is_success"][i])
    assert verdicts == [bool(ep.metrics["success"]) for ep in result.episodes]
    if task != "setpoint":  # the PD law loses some of these episodes: both verdicts are compared
        assert 0 < sum(verdicts) < episodes


def test_the_single_env_gives_the_harness_s_verdict():
    result = evaluate(PD_GC, {"task": "hold"}, episodes=3, seed=11, max_steps=200, progress=False)
    for episode in result.episodes:
        env = make(task="hold", max_episode_steps=200)
        policy = PD_GC(env)
        obs, _ = env.reset(seed=episode.seed)
        terminated = truncated = False
        while not (terminated or truncated):
            obs, _, terminated, truncated, info = env.step(policy.predict(obs)[0])
        assert bool(info["is_success"]) == bool(episode.metrics["success"])


# -- the vector environments' conventions -------------------------------------------------------------------


def test_vector_infos_hold_the_keys_with_gymnasium_s_masks():
    envs = make_vec(3, max_episode_steps=50)
    envs.reset(seed=0)
    action = np.full((3, 6), 0.09, np.float32)  # about the holding force
    action[0] = -1.0  # row 0 falls out of the workspace
    ended = None
    for k in range(40):
        _, _, terminated, _, infos = envs.step(action)
        for key, dtype in zip(SUCCESS_KEYS, (np.float64, np.float64, np.bool_)):
            assert infos[key].dtype == dtype and infos[key].shape == (3,)
            assert infos["_" + key].dtype == np.bool_
        if ended is not None and k == ended + 1:
            # row 0 is reset this step (next-step autoreset): it has no step info
            assert infos["_is_success"].tolist() == [False, True, True]
            assert infos["is_success"][0] == np.False_ and infos["position_error"][0] == 0.0
            break
        assert infos["_is_success"].all()
        if terminated[0]:
            ended = k
            assert infos["is_success"][0] == np.False_
    assert ended is not None


def test_same_step_autoreset_puts_the_verdict_in_final_info():
    envs = make_vec(2, max_episode_steps=5, autoreset_mode="SameStep")
    envs.reset(seed=0)
    for _ in range(5):
        *_, truncated, infos = envs.step(np.full((2, 6), 0.09, np.float32))
    assert truncated.all()
    final = infos["final_info"]
    assert final["_is_success"].all() and final["is_success"].dtype == np.bool_
    assert not final["is_success"].any()  # 5 steps from off target: not in the band
    assert not infos["_is_success"].any()  # the top level holds the reset info


def test_the_sb3_vec_env_reports_is_success_at_an_episode_s_end():
    pytest.importorskip("stable_baselines3")
    from stewart_env.envs import StewartPlatformSB3VecEnv

    venv = StewartPlatformSB3VecEnv(num_envs=2, max_episode_steps=200)
    policy = PD_GC(venv.venv)
    venv.seed(0)
    obs = venv.reset()
    for _ in range(200):
        obs, _, dones, infos = venv.step(policy.predict(obs)[0])
        assert all(("is_success" in info) == done for info, done in zip(infos, dones))
    assert dones.all() and [info["is_success"] for info in infos] == [True, True]


def test_the_sb3_vec_env_rows_carry_the_errors_of_the_vector_env_also_at_an_episode_s_end():
    pytest.importorskip("stable_baselines3")
    from gymnasium.vector import AutoresetMode

    from stewart_env.envs import StewartPlatformSB3VecEnv, StewartPlatformVectorEnv

    venv = StewartPlatformSB3VecEnv(num_envs=2, max_episode_steps=3)
    vector = StewartPlatformVectorEnv(num_envs=2, max_episode_steps=3, autoreset_mode=AutoresetMode.SAME_STEP)
    venv.seed(0)
    venv.reset()
    vector.reset(seed=0)
    for _ in range(3):
        action = np.full((2, 6), 0.1, np.float32)
        *_, dones, infos = venv.step(action)
        expected = vector.step(action)[-1]
    assert dones.all()  # the errors of the episode's last step, not of the reset
    for key in ("position_error", "orientation_error"):
        np.testing.assert_array_equal([info[key] for info in infos], expected["final_info"][key])
        assert all(type(info[key]) is float and info[key] > 0 for info in infos)


# -- outside tools ------------------------------------------------------------------------------------------


def test_the_env_checkers_pass():
    sb3_checker = pytest.importorskip("stable_baselines3.common.env_checker")
    from gymnasium.utils.env_checker import check_env

    for task in TASKS:
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # a checker's warning fails the test
            # but the unbounded observation box, intended (as in Gymnasium's MuJoCo environments)
            warnings.filterwarnings("ignore", message=".*Box observation space (minimum|maximum) value is")
            check_env(StewartPlatformEnv(task=task), skip_render_check=True)
            sb3_checker.check_env(StewartPlatformEnv(task=task), warn=True)


class RandomPolicy:
    """Uniform random actions, in SB3's predict interface."""

    def __init__(self, seed: int):
        self.rng = np.random.default_rng(seed)

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        return self.rng.uniform(-1.0, 1.0, (len(observation), 6)).astype(np.float32), None


def test_sb3_monitor_and_eval_callback_read_the_success_rate():
    pytest.importorskip("stable_baselines3")
    from stable_baselines3.common.callbacks import EvalCallback
    from stable_baselines3.common.evaluation import evaluate_policy
    from stable_baselines3.common.monitor import Monitor
    from stable_baselines3.common.vec_env import DummyVecEnv

    rates = {}
    for name in ("pd", "random"):
        env = DummyVecEnv([lambda: Monitor(make(max_episode_steps=200), info_keywords=("is_success",))])
        policy = PD_GC(env.envs[0]) if name == "pd" else RandomPolicy(0)
        callback = EvalCallback(env)
        monitored = []

        def read(locals_, globals_, callback=callback, monitored=monitored):  # this iteration's
            callback._log_success_callback(locals_, globals_)  # what EvalCallback's evaluation runs
            if locals_["done"]:
                monitored.append(locals_["info"]["episode"]["is_success"])

        evaluate_policy(policy, env, n_eval_episodes=2, callback=read, warn=False)
        assert len(monitored) == 2 and callback._is_success_buffer == monitored
        rates[name] = float(np.mean(callback._is_success_buffer))
    assert rates == {"pd": 1.0, "random": 0.0}


def test_eval_callback_logs_a_success_rate_while_training(tmp_path):
    pytest.importorskip("stable_baselines3")
    import csv

    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import EvalCallback
    from stable_baselines3.common.logger import configure
    from stable_baselines3.common.monitor import Monitor

    model = PPO("MlpPolicy", make(max_episode_steps=50), n_steps=64, batch_size=64, n_epochs=1, seed=0, device="cpu")
    model.set_logger(configure(str(tmp_path), ["csv"]))
    model.learn(64, callback=EvalCallback(Monitor(make(max_episode_steps=50)), n_eval_episodes=2, eval_freq=64))
    model.logger.close()
    with (tmp_path / "progress.csv").open() as f:
        logged = [row["eval/success_rate"] for row in csv.DictReader(f) if row.get("eval/success_rate")]
    assert logged == ["0.0"]  # an untrained policy drops the platform
