"""Outside RL libraries drive StewartPlatform-v1 unchanged, each through its users' normal path.

Every test here needs the `integration` extra (``pip install -e ".[rl,test,integration]"``); run
only the fast suite with ``python -m pytest -q -m "not slow and not integration"``.  Budgets are
tiny: these tests check that the libraries and the environment agree on the API, not learning.
"""

import copy
import os
import pickle
import re
import subprocess
import sys
import warnings

import gymnasium as gym
import numpy as np
import pytest

# Every test here drives an outside RL library (the integration extra); without torch none can run.
torch = pytest.importorskip("torch", reason="the integration extra is not installed")
from gymnasium.wrappers.vector import (  # noqa: E402  (after the skip without torch)
    ClipReward,
    NormalizeObservation,
    NormalizeReward,
    RecordEpisodeStatistics,
    RecordVideo,
)
from skrl_ppo import train_skrl_ppo  # noqa: E402

from stewart_env.registration import ENV_ID, MAX_EPISODE_STEPS  # noqa: E402

pytestmark = pytest.mark.integration

N_ENVS = 2
#: Gymnasium's "module:id" form imports stewart_env wherever the id is made, so a fresh worker
#: process (forkserver or spawn) finds the environment without the user importing it there.
QUALIFIED_ENV_ID = f"stewart_env:{ENV_ID}"
CONFIG_DIR = os.path.join(os.path.dirname(__file__), os.pardir, os.pardir, "configs", "agents")


@pytest.fixture(autouse=True)
def _one_torch_thread():
    """The networks here are tiny: one thread is faster than two fighting over a shared CPU."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


def _obs_dim() -> int:
    return gym.make(ENV_ID).observation_space.shape[0]


def _actions(seed: int, steps: int, n_envs: int = N_ENVS) -> np.ndarray:
    """Random forces over the full action range: episodes end within tens of steps (leg stroke)."""
    return np.random.default_rng(seed).uniform(-1.0, 1.0, (steps, n_envs, 6)).astype(np.float32)


def _headless_env() -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    env["MPLBACKEND"] = "Agg"
    return env


# -- Gymnasium ------------------------------------------------------------------------------------


def test_gymnasium_check_env_with_default_arguments_headless(headless):
    from gymnasium.utils.env_checker import check_env

    check_env(gym.make(ENV_ID).unwrapped)


def _wrapped_vector_run(mode: str, steps: int = 80):
    env = gym.make_vec(ENV_ID, num_envs=N_ENVS, vectorization_mode=mode)
    env = RecordEpisodeStatistics(ClipReward(NormalizeReward(NormalizeObservation(env)), -10.0, 10.0))
    try:
        obs, _ = env.reset(seed=7)
        observations, rewards, returns, lengths = [obs], [], [], []
        for action in _actions(0, steps):
            obs, reward, _, _, info = env.step(action)
            observations.append(obs)
            rewards.append(reward)
            if "episode" in info:
                done = info["_episode"]
                returns.extend(info["episode"]["r"][done])
                lengths.extend(info["episode"]["l"][done])
        return np.array(observations), np.array(rewards), np.array(returns), np.array(lengths)
    finally:
        env.close()


def test_make_vec_modes_agree_under_gymnasium_vector_wrappers():
    """The native batch (vector_entry_point), SyncVectorEnv and AsyncVectorEnv give bit for bit the
    same normalised observations, clipped rewards and episode statistics for the same seed and
    actions: row i of the batch is the single environment seeded s + i."""
    runs = {mode: _wrapped_vector_run(mode) for mode in ("sync", "async", "vector_entry_point")}
    obs, rewards, returns, lengths = runs["sync"]
    assert obs.shape == (81, N_ENVS, _obs_dim())
    assert np.isfinite(obs).all() and np.isfinite(rewards).all()
    assert np.abs(rewards).max() <= 10.0
    # 160 platform-steps under full-range random forces: several episodes end (leg stroke).
    assert len(lengths) >= 4 and lengths.min() >= 1
    for mode in ("async", "vector_entry_point"):
        other = runs[mode]
        for name, a, b in zip(("observations", "rewards", "returns", "lengths"), runs["sync"], other):
            np.testing.assert_array_equal(b, a, err_msg=f"{mode}: {name}")


def test_vector_record_video_on_the_native_vector_env(tmp_path):
    env = gym.make_vec(ENV_ID, num_envs=N_ENVS, vectorization_mode="vector_entry_point", render_mode="rgb_array")
    env = RecordVideo(
        env, str(tmp_path), episode_trigger=lambda episode: episode == 0, video_length=8, disable_logger=True
    )
    env.reset(seed=0)
    for action in _actions(1, 10):
        env.step(action)
    env.close()
    videos = sorted(p for p in os.listdir(tmp_path) if p.endswith(".mp4"))
    assert len(videos) == 1, os.listdir(tmp_path)
    assert os.path.getsize(tmp_path / videos[0]) > 1000


def test_native_vector_render_gives_one_frame_per_platform():
    env = gym.make_vec(ENV_ID, num_envs=N_ENVS, vectorization_mode="vector_entry_point", render_mode="rgb_array")
    try:
        env.reset(seed=0)
        frames = env.render()
        assert len(frames) == N_ENVS
        assert all(f.ndim == 3 and f.shape[2] == 3 and f.dtype == np.uint8 for f in frames)
        # Each row is its own platform with its own target (seeds 0 and 1): the pictures differ.
        assert not np.array_equal(frames[0], frames[1])
    finally:
        env.close()


# -- copies mid-episode ---------------------------------------------------------------------------


def _continue(env, actions, vector: bool):
    out = []
    for action in actions:
        obs, reward, terminated, truncated, info = env.step(action if vector else action[0])
        out.append((obs.copy(), np.copy(reward), np.copy(terminated), np.copy(truncated)))
    return out


@pytest.mark.parametrize(
    "copier", [copy.deepcopy, lambda env: pickle.loads(pickle.dumps(env))], ids=["deepcopy", "pickle"]
)
@pytest.mark.parametrize("vector", [False, True], ids=["single", "vector"])
def test_copy_mid_episode_continues_bit_identically(copier, vector):
    env = gym.make_vec(ENV_ID, num_envs=N_ENVS, vectorization_mode="vector_entry_point") if vector else gym.make(ENV_ID)
    # Small forces, seed 11: the single platform runs for 17 steps, so it is copied at step 5 and
    # followed to step 15 inside its episode; the batch is followed to step 20, through both rows'
    # ends and the first autoreset (the copied random generators draw the new targets).
    actions = 0.05 * _actions(3, 20 if vector else 15)
    env.reset(seed=11)
    _continue(env, actions[:5], vector)
    twin = copier(env)
    try:
        original, copied = _continue(env, actions[5:], vector), _continue(twin, actions[5:], vector)
        ended = np.array([terminated for _, _, terminated, _ in original])
        assert ended.any(axis=0).all() if vector else not ended.any()
        for step, (a, b) in enumerate(zip(original, copied)):
            for x, y in zip(a, b):
                np.testing.assert_array_equal(y, x, err_msg=f"step {step} after the copy")
        # The copy is independent: stepping it again does not move the original.
        before = env.unwrapped.state.position.copy() if not vector else env.state.position.copy()
        _continue(twin, actions[:3], vector)
        after = env.unwrapped.state.position if not vector else env.state.position
        np.testing.assert_array_equal(after, before)
    finally:
        env.close()
        twin.close()


# -- stable-baselines3 ----------------------------------------------------------------------------


def test_sb3_env_checker_finds_nothing_to_warn_about():
    from stable_baselines3.common.env_checker import check_env

    env = gym.make(ENV_ID)
    try:
        with warnings.catch_warnings():
            # SB3's checker reports every doubtful point of the API as a UserWarning.
            warnings.simplefilter("error", UserWarning)
            check_env(env, warn=True)
    finally:
        env.close()


@pytest.mark.slow
def test_sb3_subproc_vec_env_trains_ppo():
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import SubprocVecEnv

    # SubprocVecEnv starts its workers with forkserver: fresh processes that know the id only
    # through the module-qualified form.
    env = make_vec_env(QUALIFIED_ENV_ID, n_envs=N_ENVS, vec_env_cls=SubprocVecEnv, seed=0)
    try:
        obs = env.reset()
        assert obs.shape == (N_ENVS, _obs_dim())
        model = PPO("MlpPolicy", env, n_steps=32, batch_size=32, n_epochs=1, seed=0, device="cpu")
        model.learn(total_timesteps=64)
        assert model.num_timesteps == 64
        assert np.isfinite(model.logger.name_to_value["train/loss"])
        assert env.get_attr("spec")[0].max_episode_steps == MAX_EPISODE_STEPS
    finally:
        env.close()


# -- torchrl --------------------------------------------------------------------------------------


def _torchrl_rollout(num_envs: int, read_infos: bool, steps: int = 40):
    from torchrl.envs import GymEnv
    from torchrl.envs.utils import check_env_specs

    if num_envs > 1:
        # torchrl runs an AsyncVectorEnv whose workers it spawns (fresh processes), and reads the
        # step infos itself.
        env = GymEnv(QUALIFIED_ENV_ID, num_envs=num_envs)
    else:
        env = GymEnv(ENV_ID)
        if read_infos:
            env = env.auto_register_info_dict()
    try:
        check_env_specs(env, seed=0)
        env.set_seed(3)
        torch.manual_seed(3)
        return env.rollout(steps, break_when_any_done=False)
    finally:
        env.close()


@pytest.mark.parametrize(
    "num_envs, read_infos", [(1, False), (1, True), (N_ENVS, True)], ids=["single", "single-infos", "batched"]
)
def test_torchrl_gym_env_specs_and_rollout(num_envs, read_infos):
    td = _torchrl_rollout(num_envs, read_infos)
    batch = (40,) if num_envs == 1 else (num_envs, 40)
    assert tuple(td.batch_size) == batch
    nxt = td["next"]
    assert nxt["observation"].shape == (*batch, _obs_dim())
    assert torch.isfinite(nxt["observation"]).all() and torch.isfinite(nxt["reward"]).all()
    done = nxt["done"].reshape(batch)
    # 40 steps of random full-range forces: every platform ends at least one episode.
    assert done.reshape(-1, 40).any(dim=1).all()
    if read_infos:
        # The reward terms come through the info reader and sum to the reward (on the steps that
        # end an episode a batched env's infos are those of the reset, as in same-step autoreset).
        terms = sum(nxt[k] for k in nxt.keys() if isinstance(k, str) and k.startswith("reward_"))
        # float32 reward against the float64 sum of its terms: rounding of the cast only.
        torch.testing.assert_close(terms.float()[~done], nxt["reward"].reshape(batch)[~done], rtol=1e-5, atol=1e-5)
    # Seeded twice, the same run.
    again = _torchrl_rollout(num_envs, read_infos)
    torch.testing.assert_close(again["next", "observation"], nxt["observation"], rtol=0, atol=0)


# -- Tianshou -------------------------------------------------------------------------------------


@pytest.mark.slow
def test_tianshou_off_policy_sac_collects_and_trains():
    from tianshou.algorithm.modelfree.sac import SAC, SACPolicy
    from tianshou.algorithm.optim import AdamOptimizerFactory
    from tianshou.data import Collector, VectorReplayBuffer
    from tianshou.env import DummyVectorEnv
    from tianshou.trainer import OffPolicyTrainerParams
    from tianshou.utils.net.common import Net
    from tianshou.utils.net.continuous import ContinuousActorProbabilistic, ContinuousCritic
    from tianshou.utils.torch_utils import policy_within_training_step

    torch.manual_seed(0)
    envs = DummyVectorEnv([lambda: gym.make(ENV_ID) for _ in range(N_ENVS)])
    envs.seed(0)
    obs_shape, act_shape = envs.observation_space[0].shape, envs.action_space[0].shape
    actor = ContinuousActorProbabilistic(
        preprocess_net=Net(state_shape=obs_shape, hidden_sizes=[32]),
        action_shape=act_shape,
        unbounded=True,
        conditioned_sigma=True,
    )
    critic = ContinuousCritic(
        preprocess_net=Net(state_shape=obs_shape, action_shape=act_shape, hidden_sizes=[32], concat=True)
    )
    algorithm = SAC(
        policy=SACPolicy(actor=actor, action_space=envs.action_space[0]),
        policy_optim=AdamOptimizerFactory(lr=1e-3),
        critic=critic,
        critic_optim=AdamOptimizerFactory(lr=1e-3),
    )
    buffer = VectorReplayBuffer(2000, N_ENVS)
    collector = Collector(algorithm, envs, buffer, exploration_noise=True, raise_on_nan_in_buffer=True)
    try:
        collector.reset()
        warmup = collector.collect(n_step=200, random=True)
        assert warmup.n_collected_steps == 200 and warmup.n_collected_episodes >= 2
        stats = algorithm.run_training(
            OffPolicyTrainerParams(
                training_collector=collector,
                max_epochs=1,
                epoch_num_steps=100,
                collection_step_num_env_steps=20,
                batch_size=32,
                update_step_num_gradient_steps_per_sample=0.1,
                test_collector=None,
                verbose=False,
                show_progress=False,
            )
        )
        # 100 steps in collection steps of 20, each followed by one update step (2 gradient steps).
        assert stats.train_step == 100 and stats.update_step == 5
        assert len(buffer) == 300 and not buffer.hasnull()
        assert np.isfinite(buffer.obs_next[: len(buffer)]).all()
        with policy_within_training_step(algorithm.policy):
            losses = algorithm.update(buffer, sample_size=32)
        assert np.isfinite([losses.actor_loss, losses.critic1_loss, losses.critic2_loss]).all()
    finally:
        envs.close()


# -- skrl -----------------------------------------------------------------------------------------


def test_skrl_ppo_on_the_native_vector_env(tmp_path, headless):
    from skrl.envs.wrappers.torch import wrap_env

    torch.manual_seed(0)
    env = wrap_env(gym.make_vec(ENV_ID, num_envs=N_ENVS, vectorization_mode="vector_entry_point"), wrapper="gymnasium")
    assert env.num_envs == N_ENVS
    # headless stays at its default, False: the trainer calls env.render() every step.
    try:
        agent = train_skrl_ppo(env, tmp_path, hidden=32, timesteps=48)
        observations = agent.memory.get_tensor_by_name("observations")
        assert observations.shape == (16, N_ENVS, _obs_dim())
        assert torch.isfinite(observations).all()
        losses = [v for k, v in agent.tracking_data.items() if k.startswith("Loss")]
        assert losses and np.isfinite(np.concatenate(losses)).all()
    finally:
        env.close()


# -- a CleanRL-style PPO loop ---------------------------------------------------------------------


def _cleanrl_ppo(seed: int, updates: int = 2, n_steps: int = 64) -> list[float]:
    """CleanRL's ppo_continuous_action.py, cut to its bones: Gymnasium's normalisation wrappers on
    each env, a SyncVectorEnv, GAE and the clipped surrogate."""

    def make_env():
        env = gym.make(ENV_ID)
        env = gym.wrappers.RecordEpisodeStatistics(env)
        env = gym.wrappers.ClipAction(env)
        env = gym.wrappers.NormalizeObservation(env)
        env = gym.wrappers.TransformObservation(env, lambda o: np.clip(o, -10, 10), env.observation_space)
        env = gym.wrappers.NormalizeReward(env, gamma=0.99)
        return gym.wrappers.TransformReward(env, lambda r: float(np.clip(r, -10, 10)))

    torch.manual_seed(seed)
    envs = gym.vector.SyncVectorEnv([make_env for _ in range(N_ENVS)])
    n_obs, n_act = envs.single_observation_space.shape[0], envs.single_action_space.shape[0]
    actor = torch.nn.Sequential(torch.nn.Linear(n_obs, 64), torch.nn.Tanh(), torch.nn.Linear(64, n_act))
    critic = torch.nn.Sequential(torch.nn.Linear(n_obs, 64), torch.nn.Tanh(), torch.nn.Linear(64, 1))
    log_std = torch.nn.Parameter(torch.full((n_act,), -1.0))
    optimizer = torch.optim.Adam([*actor.parameters(), *critic.parameters(), log_std], lr=3e-4)
    losses = []
    obs, _ = envs.reset(seed=seed)
    obs, done = torch.as_tensor(obs), torch.zeros(N_ENVS)
    try:
        for _ in range(updates):
            b_obs, b_act, b_logp, b_rew, b_done, b_val = [], [], [], [], [], []
            for _ in range(n_steps):
                with torch.no_grad():
                    dist = torch.distributions.Normal(actor(obs), log_std.exp())
                    action = dist.sample()
                    b_obs.append(obs), b_act.append(action), b_done.append(done)
                    b_logp.append(dist.log_prob(action).sum(-1)), b_val.append(critic(obs).squeeze(-1))
                obs, reward, terminated, truncated, _ = envs.step(action.numpy())
                obs, done = torch.as_tensor(obs), torch.as_tensor(terminated | truncated, dtype=torch.float32)
                b_rew.append(torch.as_tensor(reward, dtype=torch.float32))
            with torch.no_grad():
                next_value, advantages, last = critic(obs).squeeze(-1), torch.zeros(n_steps, N_ENVS), 0.0
                for t in reversed(range(n_steps)):
                    not_done = 1.0 - (done if t == n_steps - 1 else b_done[t + 1])
                    value_next = next_value if t == n_steps - 1 else b_val[t + 1]
                    delta = b_rew[t] + 0.99 * value_next * not_done - b_val[t]
                    advantages[t] = last = delta + 0.99 * 0.95 * not_done * last
                returns = advantages + torch.stack(b_val)
            o, a, logp = torch.stack(b_obs).flatten(0, 1), torch.stack(b_act).flatten(0, 1), torch.stack(b_logp)
            adv = advantages.flatten()
            adv = (adv - adv.mean()) / (adv.std() + 1e-8)
            dist = torch.distributions.Normal(actor(o), log_std.exp())
            ratio = (dist.log_prob(a).sum(-1) - logp.flatten()).exp()
            pg_loss = torch.max(-adv * ratio, -adv * ratio.clamp(0.8, 1.2)).mean()
            v_loss = 0.5 * ((critic(o).squeeze(-1) - returns.flatten()) ** 2).mean()
            loss = pg_loss + 0.5 * v_loss - 0.0 * dist.entropy().sum(-1).mean()
            optimizer.zero_grad()
            loss.backward()
            torch.nn.utils.clip_grad_norm_([*actor.parameters(), *critic.parameters(), log_std], 0.5)
            optimizer.step()
            losses.append(float(loss.detach()))
    finally:
        envs.close()
    return losses


def test_cleanrl_style_ppo_loop_on_sync_vector_env():
    losses = _cleanrl_ppo(seed=1)
    assert len(losses) == 2 and np.isfinite(losses).all()
    # The environment, its wrappers and torch are seeded: a second run is the same run.
    assert _cleanrl_ppo(seed=1) == losses


# -- rl_zoo3 --------------------------------------------------------------------------------------


def _zoo(module: str, *args: str, cwd) -> str:
    cmd = [
        sys.executable,
        "-m",
        f"rl_zoo3.{module}",
        "--algo",
        "ppo",
        "--env",
        ENV_ID,
        "--gym-packages",
        "stewart_env",
        *args,
    ]
    run = subprocess.run(cmd, capture_output=True, text=True, timeout=300, cwd=cwd, env=_headless_env())
    assert run.returncode == 0, f"{' '.join(cmd)}\n{run.stdout[-2000:]}\n{run.stderr[-3000:]}"
    return run.stdout


@pytest.mark.slow
def test_rl_zoo3_trains_and_enjoys_with_the_shipped_config(tmp_path):
    # The shipped PPO entry, shrunk through rl_zoo3's own -params overrides.
    _zoo(
        "train",
        "--conf-file",
        os.path.join(CONFIG_DIR, "ppo.yml"),
        "-n",
        "128",
        "-f",
        str(tmp_path),
        "--seed",
        "0",
        "--eval-freq",
        "-1",
        "-params",
        "n_envs:2",
        "n_steps:32",
        "batch_size:32",
        "n_epochs:1",
        cwd=tmp_path,
    )
    run_dir = tmp_path / "ppo" / f"{ENV_ID}_1"
    assert (run_dir / f"{ENV_ID}.zip").is_file()
    assert (run_dir / ENV_ID / "vecnormalize.pkl").is_file()
    # enjoy renders by default (render_mode "human"); headless it draws nothing and still plays.
    out = _zoo(
        "enjoy", "-f", str(tmp_path), "--exp-id", "1", "-n", "200", "--seed", "0", "--deterministic", cwd=tmp_path
    )
    episodes = re.search(r"^(\d+) Episodes$", out, re.MULTILINE)
    mean = re.search(r"^Mean reward: (\S+) \+/- (\S+)$", out, re.MULTILINE)
    assert episodes and int(episodes.group(1)) >= 1, out[-2000:]
    assert mean and np.isfinite(float(mean.group(1))), out[-2000:]
