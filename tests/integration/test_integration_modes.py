"""Outside RL libraries drive StewartPlatform-v1 unchanged in its other action modes and on its drives.

Two pairs a real machine takes, a pose set point through electric drives and leg lengths through
hydraulic cylinders, go through each outside library's normal path as ``test_integration.py``
drives the default environment (every mode on every actuator passes Gymnasium's and
stable-baselines3's env checkers in ``tests/envs/test_actuation.py``).  All on the
``motion_simulator`` platform, the shipped one with electric and hydraulic parameter sets.  Budgets
are tiny: these tests check that the libraries and the environment agree on the API, not learning.
"""

import os
import re
import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest

# Every test here drives an outside RL library (the integration extra); without torch none can run.
torch = pytest.importorskip("torch", reason="the integration extra is not installed")

from skrl_ppo import train_skrl_ppo  # noqa: E402

from stewart_env.registration import ENV_ID  # noqa: E402  (after the skip without torch)

pytestmark = pytest.mark.integration

N_ENVS = 2
QUALIFIED_ENV_ID = f"stewart_env:{ENV_ID}"
CONFIG_DIR = os.path.join(os.path.dirname(__file__), os.pardir, os.pardir, "configs", "agents")
#: The lag actuator's time constant here, s: a drive's few tens of milliseconds.
LAG_TAU = 0.02


def _kwargs(action_mode: str, actuator: str) -> dict:
    """The environment's keywords of one mode on one actuator, on the platform with both drives."""
    out = {"platform": "motion_simulator", "action_mode": action_mode, "actuator": actuator}
    if actuator == "lag":
        out["actuator_tau"] = LAG_TAU
    return out


#: The pairs every outside library runs: a pose set point through electric drives, leg lengths
#: through hydraulic cylinders.
MACHINES = [_kwargs("pose", "electric"), _kwargs("leg_length", "hydraulic")]
MACHINE_IDS = ["pose-electric", "leg_length-hydraulic"]


@pytest.fixture(autouse=True)
def _one_torch_thread():
    """The networks here are tiny: one thread is faster than two fighting over a shared CPU."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


def _obs_dim(kwargs: dict) -> int:
    env = gym.make(ENV_ID, **kwargs)
    try:
        return env.observation_space.shape[0]
    finally:
        env.close()


def _actions(seed: int, steps: int, n_envs: int = N_ENVS) -> np.ndarray:
    """Random set points (or forces) over the full action range."""
    return np.random.default_rng(seed).uniform(-1.0, 1.0, (steps, n_envs, 6)).astype(np.float32)


# -- stable-baselines3 ----------------------------------------------------------------------------


@pytest.mark.slow
@pytest.mark.parametrize("kwargs", MACHINES, ids=MACHINE_IDS)
def test_sb3_subproc_vec_env_trains_ppo_on_a_machine(kwargs):
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import SubprocVecEnv

    env = make_vec_env(QUALIFIED_ENV_ID, n_envs=N_ENVS, vec_env_cls=SubprocVecEnv, seed=0, env_kwargs=kwargs)
    try:
        assert env.reset().shape == (N_ENVS, _obs_dim(kwargs))
        model = PPO("MlpPolicy", env, n_steps=128, batch_size=64, n_epochs=1, seed=0, device="cpu")
        model.learn(total_timesteps=256)
        assert model.num_timesteps == 256
        assert np.isfinite(model.logger.name_to_value["train/loss"])
        assert env.get_attr("spec")[0].kwargs["action_mode"] == kwargs["action_mode"]
    finally:
        env.close()


# -- torchrl --------------------------------------------------------------------------------------


def _torchrl_rollout(kwargs: dict, steps: int = 30):
    from torchrl.envs import GymEnv
    from torchrl.envs.utils import check_env_specs

    env = GymEnv(ENV_ID, **kwargs).auto_register_info_dict()
    try:
        check_env_specs(env, seed=0)
        env.set_seed(3)
        torch.manual_seed(3)
        return env.rollout(steps, break_when_any_done=False)
    finally:
        env.close()


@pytest.mark.parametrize("kwargs", MACHINES, ids=MACHINE_IDS)
def test_torchrl_gym_env_specs_and_rollout_on_a_machine(kwargs):
    td = _torchrl_rollout(kwargs)
    assert tuple(td.batch_size) == (30,)
    nxt = td["next"]
    assert nxt["observation"].shape == (30, _obs_dim(kwargs))
    assert torch.isfinite(nxt["observation"]).all() and torch.isfinite(nxt["reward"]).all()
    # The constraint cost comes through the info reader, one finite non-negative value a step.
    assert nxt["cost"].shape[0] == 30 and (nxt["cost"] >= 0).all()
    again = _torchrl_rollout(kwargs)
    torch.testing.assert_close(again["next", "observation"], nxt["observation"], rtol=0, atol=0)


# -- Tianshou -------------------------------------------------------------------------------------


@pytest.mark.parametrize("kwargs", MACHINES, ids=MACHINE_IDS)
def test_tianshou_collector_on_a_machine(kwargs):
    from tianshou.algorithm.modelfree.sac import SAC, SACPolicy
    from tianshou.algorithm.optim import AdamOptimizerFactory
    from tianshou.data import Collector, VectorReplayBuffer
    from tianshou.env import DummyVectorEnv
    from tianshou.utils.net.common import Net
    from tianshou.utils.net.continuous import ContinuousActorProbabilistic, ContinuousCritic

    torch.manual_seed(0)
    envs = DummyVectorEnv([lambda: gym.make(ENV_ID, **kwargs) for _ in range(N_ENVS)])
    envs.seed(0)
    obs_shape, act_shape = envs.observation_space[0].shape, envs.action_space[0].shape
    actor = ContinuousActorProbabilistic(
        preprocess_net=Net(state_shape=obs_shape, hidden_sizes=[16]),
        action_shape=act_shape,
        unbounded=True,
        conditioned_sigma=True,
    )
    critic = ContinuousCritic(
        preprocess_net=Net(state_shape=obs_shape, action_shape=act_shape, hidden_sizes=[16], concat=True)
    )
    algorithm = SAC(
        policy=SACPolicy(actor=actor, action_space=envs.action_space[0]),
        policy_optim=AdamOptimizerFactory(lr=1e-3),
        critic=critic,
        critic_optim=AdamOptimizerFactory(lr=1e-3),
    )
    buffer = VectorReplayBuffer(400, N_ENVS)
    collector = Collector(algorithm, envs, buffer, exploration_noise=True, raise_on_nan_in_buffer=True)
    try:
        collector.reset()
        stats = collector.collect(n_step=100, random=True)
        assert stats.n_collected_steps == 100
        assert len(buffer) == 100 and not buffer.hasnull()
        assert np.isfinite(buffer.obs_next[: len(buffer)]).all()
        assert np.abs(buffer.act[: len(buffer)]).max() <= 1.0
    finally:
        envs.close()


# -- skrl -----------------------------------------------------------------------------------------


@pytest.mark.parametrize("kwargs", MACHINES, ids=MACHINE_IDS)
def test_skrl_ppo_on_the_native_vector_env_on_a_machine(kwargs, tmp_path, headless):
    from skrl.envs.wrappers.torch import wrap_env

    torch.manual_seed(0)
    env = wrap_env(
        gym.make_vec(ENV_ID, num_envs=N_ENVS, vectorization_mode="vector_entry_point", **kwargs), wrapper="gymnasium"
    )
    try:
        agent = train_skrl_ppo(env, tmp_path, hidden=16, timesteps=32)
        observations = agent.memory.get_tensor_by_name("observations")
        assert observations.shape == (16, N_ENVS, _obs_dim(kwargs))
        assert torch.isfinite(observations).all()
        losses = [v for k, v in agent.tracking_data.items() if k.startswith("Loss")]
        assert losses and np.isfinite(np.concatenate(losses)).all()
    finally:
        env.close()


# -- rl_zoo3 with the shipped configs of the modes ------------------------------------------------


def _headless_env() -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    env["MPLBACKEND"] = "Agg"
    return env


def _zoo(module: str, *args: str, cwd) -> str:
    cmd = [sys.executable, "-m", f"rl_zoo3.{module}", "--algo", "ppo", "--env", ENV_ID, "--gym-packages", "stewart_env"]
    run = subprocess.run([*cmd, *args], capture_output=True, text=True, timeout=300, cwd=cwd, env=_headless_env())
    assert run.returncode == 0, f"{' '.join(cmd)}\n{run.stdout[-2000:]}\n{run.stderr[-3000:]}"
    return run.stdout


@pytest.mark.slow
@pytest.mark.parametrize(
    "config, actuator", [("ppo_pose.yml", "electric"), ("ppo_leg_length.yml", "hydraulic")], ids=MACHINE_IDS
)
def test_rl_zoo3_trains_and_enjoys_with_the_shipped_mode_config(config, actuator, tmp_path):
    # The shipped entry of the mode, the drive and the platform added by rl_zoo3's --env-kwargs.
    drive = ["--env-kwargs", "platform:'motion_simulator'", f"actuator:'{actuator}'"]
    _zoo(
        "train",
        "--conf-file",
        os.path.join(CONFIG_DIR, config),
        "-n",
        "128",
        "-f",
        str(tmp_path),
        "--seed",
        "0",
        "--eval-freq",
        "-1",
        *drive,
        "-params",
        "n_envs:2",
        "n_steps:32",
        "batch_size:32",
        "n_epochs:1",
        cwd=tmp_path,
    )
    run_dir = tmp_path / "ppo" / f"{ENV_ID}_1"
    assert (run_dir / f"{ENV_ID}.zip").is_file()
    out = _zoo(
        "enjoy",
        "-f",
        str(tmp_path),
        "--exp-id",
        "1",
        "-n",
        "100",
        "--seed",
        "0",
        "--deterministic",
        *drive,
        cwd=tmp_path,
    )
    mean = re.search(r"^Mean reward: (\S+) \+/- (\S+)$", out, re.MULTILINE)
    # A 5 s episode is 500 steps: 100 steps end none, and enjoy then reports no mean; it played.
    assert mean is None or np.isfinite(float(mean.group(1))), out[-2000:]
