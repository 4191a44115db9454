"""Cueing by PPO warm-started from the model-predictive cueing: a network that imitates the MPC's
programmes, then PPO on the cueing task's reward.

The cueing MPC (:mod:`stewart_env.agents.controllers.cueing_mpc`) solves one quadratic programme
per pair of axes at every step; what it commands is the first input of each programme, the jerk
and the angular acceleration u (3 pairs x 2), as a function of its state (the model's motion, the
perception filters' states, :meth:`~stewart_env.agents.controllers.cueing_mpc.CueingMPC.features`)
and of the reference the environment observes (the vehicle's sample and preview).  Here a network
replaces the programmes: the agent observes the environment's observation followed by the
controller's 39 state values (both standardised by the demonstrations' mean and deviation) and
its action is u, standardised the same way; the controller's model integrates it and commands the
pose through the pose loop's inverse, as the MPC does (:meth:`CueingMPCPolicy.prepare
<stewart_env.agents.controllers.cueing_mpc.CueingMPCPolicy.prepare>` and ``command``).  The jerk
is integrated three times before it moves the pose, so that an imitation's error is not felt as a
step-to-step jitter.

Training (:func:`train_imitation`, a zoo-format config whose entry holds :data:`IMITATION_KEY`,
``configs/agents/ppo_cueing_mpc.yml``):

1. **demonstrations**: the MPC drives the training motions (each of
   :data:`~stewart_env.tasks.cueing.motions.TRAINING_MOTIONS` at the training seeds
   0 .. ``seeds`` - 1, at most ``max_steps`` steps each), and every step's observation, state and
   programmes' inputs are kept;
2. **cloning**: PPO's policy mean is fitted to the inputs by least squares (Adam, ``epochs`` passes);
3. **DAgger** (Ross, Gordon and Bagnell, 2011), ``rounds`` times: the clone drives the same
   motions while the MPC's programmes, solved from the clone's states, label every step; the
   labels join the demonstrations and the mean is fitted again, so that the clone learns what the
   MPC would do in the states its own errors lead to;
4. **PPO** on the cueing task's reward from the clone, for the config's ``n_timesteps``.

**PPO as a residual on the MPC** (the entry's key :data:`RESIDUAL_MPC_KEY`, with
``residual_scale`` > 0; ``configs/agents/ppo_cueing_mpc_residual.yml``): the programmes are solved
at every step, and the agent's action, in the demonstrations' deviations of the inputs and times
``residual_scale``, is added to their inputs (residual policy learning, Silver et al. 2018;
Johannink et al. 2019).  The demonstrations give only the standardisation; there is no fit: the
policy's mean starts at zero, so that an untrained agent cues exactly as the MPC does, and the
MPC's next programme, solved from the state the residual led to, takes its bounds and false cues
into account.

An agent's folder holds ``model.zip`` (SB3's), ``imitation.npz`` (the standardisations) and
``imitation.json`` (the settings, the files' sha256, checked before they are read, and the
training's CPU and wall time by stage).
"""

from __future__ import annotations

import collections
import functools
import io
import json
import os
import time
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from stewart_env.agents.training.environment import single_thread
from stewart_env.agents.training.errors import TrainingError
from stewart_env.agents.training.residual import _vec_env_wrapper
from stewart_env.agents.training.rundir import sha256_hex
from stewart_env.files import publish

__all__ = [
    "IMITATION_KEY",
    "RESIDUAL_MPC_KEY",
    "ImitatedMPCPolicy",
    "ImitatedMPCVecEnv",
    "ImitationSettings",
    "Standardisation",
    "demonstrations",
    "imitation_settings",
    "mean_inputs",
    "load_imitation",
    "train_imitation",
]

#: The config entry's key of the imitation's settings (:class:`ImitationSettings`' fields).
IMITATION_KEY = "imitate_mpc"
#: The config entry's key of a residual on the MPC (the same fields, ``residual_scale`` > 0).
RESIDUAL_MPC_KEY = "residual_mpc"
#: The largest residual scale, in the inputs' deviations per unit of action.
MAX_RESIDUAL_SCALE = 10.0
#: The files of a trained agent.
MODEL_FILE, SCALES_FILE, MANIFEST = "model.zip", "imitation.npz", "imitation.json"
#: The controller's state values the agent observes after the environment's observation.
FEATURES = 39
#: The largest standardised input a demonstration may hold: beyond it a programme's solution is
#: taken as a solver's failure, not as cueing (the MPC's inputs lie within a few deviations).
MAX_STANDARD_INPUT = 50.0
#: PPO's action bound, in the inputs' deviations.
ACTION_BOUND = 20.0


@dataclass(frozen=True)
class ImitationSettings:
    """How the MPC is imitated before PPO.

    Attributes:
        seeds: training seeds per motion (0 .. seeds - 1) of the demonstrations, 1 to 64.
        max_steps: control steps of a demonstration episode at most, 10 to 100000.
        rounds: DAgger rounds after the demonstrations, 0 to 10.
        epochs: passes of the fit over the samples, each time it is fitted, 1 to 1000.
        batch_size: samples per gradient step, 16 to 65536.
        learning_rate: Adam's step size of the fit, in (0, 1].
        residual_scale: 0: the agent's action replaces the MPC's inputs (the imitation); in
            (0, 10]: it is added to them, a unit of action moving each input by this many of its
            deviations (the residual; no fit and no DAgger round).
    """

    seeds: int = 4
    max_steps: int = 1000
    rounds: int = 0
    epochs: int = 30
    batch_size: int = 512
    learning_rate: float = 1e-3
    residual_scale: float = 0.0

    def __post_init__(self) -> None:
        scale = self.residual_scale
        if isinstance(scale, bool) or not isinstance(scale, (int, float)) or not 0.0 <= scale <= MAX_RESIDUAL_SCALE:
            raise TrainingError(
                f"{RESIDUAL_MPC_KEY}: residual_scale must be a number in [0, {MAX_RESIDUAL_SCALE:g}], got {scale!r}"
            )
        for name, low, high in (
            ("seeds", 1, 64),
            ("max_steps", 10, 100000),
            ("rounds", 0, 10),
            ("epochs", 1, 1000),
            ("batch_size", 16, 65536),
        ):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not low <= value <= high:
                raise TrainingError(f"{self.key}: {name} must be an integer in [{low}, {high}], got {value!r}")
        rate = self.learning_rate
        if isinstance(rate, bool) or not isinstance(rate, (int, float)) or not 0.0 < float(rate) <= 1.0:
            raise TrainingError(f"{self.key}: learning_rate must be a number in (0, 1], got {rate!r}")
        if self.residual and self.rounds:
            raise TrainingError(f"{self.key}: a residual on the MPC has no DAgger rounds, got rounds={self.rounds}")

    @property
    def residual(self) -> bool:
        """Whether the agent's action is added to the MPC's inputs rather than replacing them."""
        return self.residual_scale > 0

    @property
    def key(self) -> str:
        """The config entry's key of these settings."""
        return RESIDUAL_MPC_KEY if self.residual else IMITATION_KEY


def imitation_settings(entry: Mapping[str, Any]) -> tuple[ImitationSettings, dict[str, Any]]:
    """Split a zoo entry into the imitation's (or the residual's) settings and the entry SB3's
    parser reads.

    Args:
        entry: the config's entry (``read_hyperparameters``).

    Returns:
        (the settings, the entry without :data:`IMITATION_KEY` or :data:`RESIDUAL_MPC_KEY`).

    Raises:
        TrainingError: both keys or neither, a value that is not a mapping, or a bad value
            (under :data:`RESIDUAL_MPC_KEY`, ``residual_scale`` must be given and > 0).
    """
    keys = [k for k in (IMITATION_KEY, RESIDUAL_MPC_KEY) if k in entry]
    if len(keys) != 1:
        raise TrainingError(f"give one of {IMITATION_KEY} or {RESIDUAL_MPC_KEY}, got {keys or 'neither'}")
    key = keys[0]
    value = entry[key]
    if not isinstance(value, Mapping):
        raise TrainingError(f"{key}: the config needs a mapping {key}: {{seeds, rounds, ...}}")
    fields = tuple(ImitationSettings.__dataclass_fields__)
    unknown = sorted(set(value) - set(fields))
    if unknown:
        raise TrainingError(f"{key}: unknown key(s) {', '.join(map(str, unknown))}; valid: {', '.join(fields)}")
    if key == RESIDUAL_MPC_KEY and not value.get("residual_scale"):
        raise TrainingError(f"{key}: residual_scale must be given, > 0 (the residual's size in the inputs' deviations)")
    if key == IMITATION_KEY and value.get("residual_scale"):
        raise TrainingError(f"{key}: residual_scale is {RESIDUAL_MPC_KEY}'s; an imitation replaces the MPC's inputs")
    rest = {k: v for k, v in entry.items() if k != key}
    return ImitationSettings(**value), rest


class Standardisation:
    """The demonstrations' means and deviations: of what the agent observes (the observation and
    the controller's state) and of the inputs.

    Args:
        x_mean, x_scale: (obs_dim + 39,) the observed values' means and deviations (at least 1e-6).
        u_mean, u_scale: (6,) the inputs'.
    """

    def __init__(self, x_mean, x_scale, u_mean, u_scale):
        self.x_mean, self.x_scale = np.asarray(x_mean, dtype=float), np.asarray(x_scale, dtype=float)
        self.u_mean, self.u_scale = np.asarray(u_mean, dtype=float), np.asarray(u_scale, dtype=float)

    @classmethod
    def of(cls, x: np.ndarray, u: np.ndarray) -> Standardisation:
        """The standardisation of samples.

        Args:
            x: (n, obs_dim + 39) the observations and the controller's states.
            u: (n, 6) the inputs.
        """
        return cls(x.mean(axis=0), np.maximum(x.std(axis=0), 1e-6), u.mean(axis=0), np.maximum(u.std(axis=0), 1e-12))

    def observed(self, observation: np.ndarray, features: np.ndarray) -> np.ndarray:
        """What the agent observes: (N, obs_dim + 39) float32.

        Args:
            observation: (N, obs_dim) the environment's observations.
            features: (N, 39) the controller's states.
        """
        x = np.concatenate([np.atleast_2d(observation).astype(float), features], axis=1)
        return ((x - self.x_mean) / self.x_scale).astype(np.float32)

    def inputs(self, action) -> np.ndarray:
        """The programmes' inputs (N, 3, 2) of standardised actions, clipped to the action's bound.

        Args:
            action: (N, 6) standardised actions.
        """
        a = np.clip(np.asarray(action, dtype=float).reshape(-1, 6), -ACTION_BOUND, ACTION_BOUND)
        return (a * self.u_scale + self.u_mean).reshape(-1, 3, 2)

    def residual(self, action, scale: float) -> np.ndarray:
        """The corrections (N, 3, 2) of standardised actions, clipped to the action's bound.

        Args:
            action: (N, 6) the agent's actions.
            scale: the inputs' deviations per unit of action.
        """
        a = np.clip(np.asarray(action, dtype=float).reshape(-1, 6), -ACTION_BOUND, ACTION_BOUND)
        return (a * (scale * self.u_scale)).reshape(-1, 3, 2)

    def actions(self, inputs: np.ndarray) -> np.ndarray:
        """The standardised actions (N, 6) float32 of inputs.

        Args:
            inputs: (N, 6) or (N, 3, 2) the programmes' inputs.
        """
        return ((np.asarray(inputs, dtype=float).reshape(-1, 6) - self.u_mean) / self.u_scale).astype(np.float32)

    def arrays(self) -> dict[str, np.ndarray]:
        """The arrays as ``imitation.npz`` stores them."""
        return {"x_mean": self.x_mean, "x_scale": self.x_scale, "u_mean": self.u_mean, "u_scale": self.u_scale}


def _controller(env):
    from stewart_env.agents.controllers.cueing_mpc import CueingMPCPolicy

    controller = CueingMPCPolicy(env)
    if not controller.preview:
        raise TrainingError("the imitated MPC needs the task option preview > 0 (the configs' preview: 100)")
    return controller


def demonstrations(
    settings: ImitationSettings, env_kwargs: Mapping[str, Any], clone=None, progress: bool = False
) -> tuple[np.ndarray, np.ndarray]:
    """The MPC's inputs on the training motions, side by side in one vector environment.

    Args:
        settings: which motions and how long.
        env_kwargs: the environment's keywords (pose mode, a preview).
        clone: None (the MPC drives) or a callable (observation (N, obs_dim), features (N, 39)) ->
            inputs (N, 3, 2) that drives while the MPC's programmes label each step (DAgger).
        progress: a progress bar on a terminal.

    Returns:
        (x (n, obs_dim + 39): the observations and the controller's states, u (n, 6): the
        programmes' inputs), the steps of every episode until it ends, its motion ends or
        ``max_steps``; a step whose programme failed (a non-finite or outsized input) is left out.
    """
    from stewart_env.envs.vector import StewartPlatformVectorEnv
    from stewart_env.progress import progress as progress_bar
    from stewart_env.tasks.cueing.motions import TRAINING_MOTIONS

    episodes = [(name, seed) for name in TRAINING_MOTIONS for seed in range(settings.seeds)]
    kwargs = {k: v for k, v in env_kwargs.items() if k != "max_episode_steps"}
    options = {**kwargs.pop("task_options", {}), "motions": TRAINING_MOTIONS, "training_seeds": settings.seeds}
    env = StewartPlatformVectorEnv(num_envs=len(episodes), task="cueing", task_options=options, **kwargs)
    xs, us = [], []
    try:
        env.task.schedule(episodes)
        controller = _controller(env)
        obs, _ = env.reset(seed=0)
        alive = np.ones(len(episodes), dtype=bool)
        bar = progress_bar(
            total=settings.max_steps,
            desc="MPC demonstrations" if clone is None else "DAgger",
            unit="step",
            disable=not progress,
        )
        for _ in range(settings.max_steps):
            features = controller.prepare(obs)
            label = controller.mpc.solve()
            xs.append(np.concatenate([obs, features], axis=1)[alive])
            us.append(label.reshape(-1, 6)[alive])
            inputs = label if clone is None else clone(obs, features)
            obs, _, terminated, truncated, _ = env.step(controller.command(inputs))
            alive &= ~(terminated | truncated)
            bar.update(1)
            if not alive.any():
                break
        bar.close()
    finally:
        env.close()
    x, u = np.concatenate(xs), np.concatenate(us)
    return x, u


def _kept(x: np.ndarray, u: np.ndarray, reference: Standardisation | None) -> tuple[np.ndarray, np.ndarray]:
    """The samples whose values are finite and whose inputs lie within MAX_STANDARD_INPUT deviations."""
    ok = np.all(np.isfinite(x), axis=1) & np.all(np.isfinite(u), axis=1)
    scale = reference or Standardisation.of(x[ok], u[ok])
    median = np.median(u[ok], axis=0)
    ok &= np.all(np.abs(u - median) <= MAX_STANDARD_INPUT * scale.u_scale, axis=1)
    return x[ok], u[ok]


def _policy_mean(policy, x):
    """The SB3 policy's mean action of observations ``x`` (a torch tensor), differentiable."""
    features = policy.extract_features(x, policy.pi_features_extractor)
    latent, _ = policy.mlp_extractor(features)
    return policy.action_net(latent)


def fit_clone(policy, x: np.ndarray, y: np.ndarray, settings: ImitationSettings, seed: int) -> float:
    """Fit the policy's mean to ``y`` (standardised inputs) on ``x`` (what it observes) by least
    squares: Adam with a cosine-decayed step over ``epochs`` passes of shuffled batches.

    Args:
        policy: SB3's ActorCriticPolicy.
        x: (n, obs_dim + 39) standardised observed values.
        y: (n, 6) standardised inputs.
        settings: the fit's epochs, batch size and step size.
        seed: the batches' shuffling.

    Returns:
        The last pass's mean squared error.
    """
    import torch

    generator = torch.Generator().manual_seed(seed)
    inputs, targets = torch.as_tensor(x, dtype=torch.float32), torch.as_tensor(y, dtype=torch.float32)
    parameters = [*policy.mlp_extractor.policy_net.parameters(), *policy.action_net.parameters()]
    optimiser = torch.optim.Adam(parameters, lr=settings.learning_rate)
    schedule = torch.optim.lr_scheduler.CosineAnnealingLR(optimiser, settings.epochs)
    policy.set_training_mode(True)
    n, loss_sum = len(inputs), 0.0
    for _ in range(settings.epochs):
        loss_sum = 0.0
        for batch in torch.randperm(n, generator=generator).split(settings.batch_size):
            loss = ((_policy_mean(policy, inputs[batch]) - targets[batch]) ** 2).mean()
            optimiser.zero_grad()
            loss.backward()
            optimiser.step()
            loss_sum += loss.item() * len(batch)
        schedule.step()
    policy.set_training_mode(False)
    return loss_sum / n


def _fit_samples(policy, scales: Standardisation, x, u, settings: ImitationSettings, seed: int) -> float:
    """:func:`fit_clone` on raw samples (x: observations and states, u: inputs), standardised."""
    return fit_clone(policy, scales.observed(x[:, :-FEATURES], x[:, -FEATURES:]), scales.actions(u), settings, seed)


class ImitatedMPCVecEnv(_vec_env_wrapper()):
    """PPO's training batch: SB3's VecEnv whose action is the standardised inputs of the
    controller's three pairs and whose observation is the standardised observation and state.

    Args:
        venv: a :class:`~stewart_env.envs.StewartPlatformSB3VecEnv` on ``task="cueing"`` in pose
            mode with a preview.
        scales: the demonstrations' standardisation.
        residual_scale: 0: the action is the inputs; > 0: it is added to the MPC's, times this
            many of the inputs' deviations.
    """

    def __init__(self, venv, scales: Standardisation, residual_scale: float = 0.0):
        from gymnasium import spaces

        size = venv.observation_space.shape[0] + FEATURES
        observation_space = spaces.Box(-np.inf, np.inf, (size,), np.float32)
        action_space = spaces.Box(-ACTION_BOUND, ACTION_BOUND, (6,), np.float32)
        super().__init__(venv, observation_space=observation_space, action_space=action_space)
        self.scales = scales
        self.residual_scale = float(residual_scale)
        self.controller = _controller(venv.venv)
        self._reasons = tuple(venv.venv.unwrapped.termination_reasons)
        #: how the training's episodes ended, by reason ("time_limit": truncated)
        self.endings: collections.Counter = collections.Counter()

    def reset(self) -> np.ndarray:
        """Every row starts over, the controller too."""
        obs = self.venv.reset()
        self.controller.reset()
        return self.scales.observed(obs, self.controller.prepare(obs))

    def step_async(self, actions: np.ndarray) -> None:
        """Command the poses of the agent's inputs (or of the MPC's, corrected by the agent's).

        Args:
            actions: (N, 6) the standardised inputs or corrections.
        """
        self.venv.step_async(
            self.controller.command(_inputs(self.controller, self.scales, self.residual_scale, actions))
        )

    def step_wait(self):
        """Step the batch; the controller starts over on the rows that ended."""
        obs, rewards, dones, infos = self.venv.step_wait()
        for i in np.flatnonzero(dones):
            reason = "time_limit" if infos[i].get("TimeLimit.truncated") else self._reasons[infos[i]["termination"]]
            self.endings[reason] += 1
            terminal = infos[i].get("terminal_observation")
            if terminal is not None:  # the state is the row's last one: only a truncation bootstraps from it
                state = self.controller.mpc.features()[i : i + 1]
                infos[i]["terminal_observation"] = self.scales.observed(terminal[None], state)[0]
        features = self.controller.prepare(obs, episode_start=dones)
        return self.scales.observed(obs, features), rewards, dones, infos


def _inputs(controller, scales: Standardisation, residual_scale: float, actions) -> np.ndarray:
    """The inputs (N, 3, 2) of the agent's actions: themselves, or the MPC's corrected by them."""
    if residual_scale > 0:
        return controller.mpc.solve() + scales.residual(actions, residual_scale)
    return scales.inputs(actions)


def _mean_action(model, scales: Standardisation, observation, features) -> np.ndarray:
    """A model's mean action (N, 6) for raw observations and the controller's states."""
    with single_thread():
        action, _ = model.predict(scales.observed(observation, features), deterministic=True)
    return action


def mean_inputs(model, scales: Standardisation, observation, features) -> np.ndarray:
    """A model's inputs (N, 3, 2), its mean action, for raw observations and the controller's states.

    Args:
        model: the SB3 model.
        scales: its standardisation.
        observation: (N, obs_dim) raw observations.
        features: (N, 39) the controller's states.
    """
    return scales.inputs(_mean_action(model, scales, observation, features))


class ImitatedMPCPolicy:
    """A trained agent on a cueing environment, with SB3's ``predict`` on raw observations.

    Args:
        env: the cueing environment (single, vector or SB3 VecEnv), pose mode, with the
            agent's preview.
        model: the trained SB3 model.
        scales: its standardisation.
        residual_scale: 0: the agent's action is the inputs; > 0: it corrects the MPC's.
    """

    def __init__(self, env, model, scales: Standardisation, residual_scale: float = 0.0):
        self.controller = _controller(env)
        self.model = model
        self.scales = scales
        self.residual_scale = float(residual_scale)

    def reset(self) -> None:
        """Start the controller over (a new batch of episodes)."""
        self.controller.reset()

    def inputs(self, observation, features) -> np.ndarray:
        """The agent's inputs (N, 3, 2), of its mean action (the controller prepared for this step).

        Args:
            observation: (N, obs_dim) raw observations.
            features: (N, 39) the controller's states.
        """
        action = _mean_action(self.model, self.scales, observation, features)
        return _inputs(self.controller, self.scales, self.residual_scale, action)

    def predict(self, observation, state=None, episode_start=None, deterministic: bool = True):
        """SB3's interface: (action (6,) or (N, 6), None).

        Args:
            observation: one raw observation (obs_dim,) or a batch (N, obs_dim).
            state: unused.
            episode_start: SB3's episode starts (N,): those rows' controller starts over.
            deterministic: unused: the agent's mean action (its cueing is judged without
                exploration noise).

        Returns:
            (action, None).
        """
        obs = np.atleast_2d(np.asarray(observation, dtype=float))
        features = self.controller.prepare(obs, episode_start)
        action = self.controller.command(self.inputs(obs, features))
        return (action[0] if np.ndim(observation) == 1 else action), None


def train_imitation(
    out: str | os.PathLike,
    config: str | os.PathLike,
    seed: int = 0,
    timesteps: int | None = None,
    env_kwargs: Mapping[str, Any] | None = None,
    n_envs: int | None = None,
    progress_bar: bool = False,
) -> dict[str, Any]:
    """Train one agent (module docstring: demonstrations, cloning, DAgger, PPO) into ``out``.

    Args:
        out: the agent's folder (created; its files replaced).
        config: a PPO zoo config with :data:`IMITATION_KEY` or :data:`RESIDUAL_MPC_KEY` (a shipped
            name or a path).
        seed: seeds torch, numpy, the fit's batches and the platforms (row i gets seed + i).
        timesteps: PPO's environment steps after the imitation (default the config's
            n_timesteps; 0: the clone alone, or for a residual the MPC itself).
        env_kwargs: environment keywords over the config's.
        n_envs: platforms in PPO's batch (default the config's n_envs).
        progress_bar: progress bars on a terminal.

    Returns:
        The manifest written to ``out/imitation.json``.

    Raises:
        TrainingError: a bad config.
    """
    import torch
    from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

    from stewart_env.agents.training.hyperparameters import (
        algorithm_class,
        parse_hyperparameters,
        read_hyperparameters,
    )
    from stewart_env.envs import StewartPlatformSB3VecEnv

    entry = read_hyperparameters("ppo", config)
    settings, rest = imitation_settings(entry)
    hp = parse_hyperparameters("ppo", rest)
    kwargs = {**hp.env_kwargs, **(env_kwargs or {}), "task": "cueing"}
    steps = hp.n_timesteps if timesteps is None else int(timesteps)
    if steps < 0:
        raise TrainingError(f"timesteps must be >= 0, got {timesteps!r}")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    demo_kwargs = {k: v for k, v in kwargs.items() if k != "task"}
    seconds: dict[str, float] = {}
    cpu, wall = time.process_time(), time.perf_counter()
    with single_thread():
        torch.manual_seed(seed)
        x, u = _kept(*demonstrations(settings, demo_kwargs, progress=progress_bar), None)
        scales = Standardisation.of(x, u)
        seconds["demonstrations"] = time.process_time() - cpu
        raw = StewartPlatformSB3VecEnv(num_envs=hp.n_envs if n_envs is None else int(n_envs), **kwargs)
        raw.seed(seed)
        imitated = ImitatedMPCVecEnv(raw, scales, settings.residual_scale)
        env = VecMonitor(imitated, info_keywords=("termination",))
        if hp.normalize is not None:
            env = VecNormalize(env, **{**hp.normalize, "norm_obs": False})  # observed values are standardised
        try:
            agent = algorithm_class("ppo")(env=env, seed=seed, device="cpu", verbose=0, **hp.algorithm_kwargs)
            if settings.residual:  # a zero mean: the untrained agent is the MPC
                with torch.no_grad():
                    agent.policy.action_net.weight.zero_()
                    agent.policy.action_net.bias.zero_()
                losses = []
            else:
                losses = [_fit_samples(agent.policy, scales, x, u, settings, seed)]
            seconds["cloning"] = time.process_time() - cpu - sum(seconds.values())
            samples = [len(x)]
            for _ in range(settings.rounds):
                more_x, more_u = _kept(
                    *demonstrations(
                        settings,
                        demo_kwargs,
                        clone=functools.partial(mean_inputs, agent, scales),
                        progress=progress_bar,
                    ),
                    scales,
                )
                x, u = np.concatenate([x, more_x]), np.concatenate([u, more_u])
                samples.append(len(more_x))
                losses.append(_fit_samples(agent.policy, scales, x, u, settings, seed))
            seconds["dagger"] = time.process_time() - cpu - sum(seconds.values())
            if steps > 0:
                agent.learn(total_timesteps=steps, progress_bar=progress_bar)
            seconds["ppo"] = time.process_time() - cpu - sum(seconds.values())
            cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
            model = io.BytesIO()
            agent.save(model)
            arrays = io.BytesIO()
            np.savez(arrays, **scales.arrays())
            files = {MODEL_FILE: model.getvalue(), SCALES_FILE: arrays.getvalue()}
        finally:
            env.close()
    for name, data in files.items():
        publish(out / name, data)
    manifest = {
        "algo": "ppo",
        "config": str(config),
        "seed": seed,
        "num_timesteps": int(agent.num_timesteps),
        "env_kwargs": kwargs,
        "imitation": asdict(settings),
        "samples": samples,
        "clone_mse": losses,
        "cpu_seconds": cpu,
        "cpu_seconds_by_stage": seconds,
        "wall_seconds": wall,
        "episode_endings": {"all": dict(imitated.endings)},
        "files": {name: sha256_hex(data) for name, data in files.items()},
    }
    publish(out / MANIFEST, json.dumps(manifest, indent=2) + "\n")
    return manifest


def load_imitation(directory: str | os.PathLike, env) -> ImitatedMPCPolicy:
    """The agent trained in ``directory`` by :func:`train_imitation`, on ``env``.

    Args:
        directory: the agent's folder.
        env: the cueing environment it will drive (pose mode, the agent's preview).

    Returns:
        The policy.

    Raises:
        TrainingError: no finished agent there, or a file whose sha256 is not the manifest's.
    """
    path = Path(directory)
    try:
        manifest = json.loads((path / MANIFEST).read_text())
        hashes = manifest["files"]
    except (OSError, ValueError, KeyError, TypeError) as err:
        raise TrainingError(f"{path}: no imitation agent ({MANIFEST}: {err})") from None
    from stewart_env.agents.training.hyperparameters import algorithm_class
    from stewart_env.agents.training.rundir import verified_bytes

    data = {name: verified_bytes(path, hashes, name, MANIFEST) for name in (MODEL_FILE, SCALES_FILE)}
    with np.load(io.BytesIO(data[SCALES_FILE]), allow_pickle=False) as arrays:
        scales = Standardisation(arrays["x_mean"], arrays["x_scale"], arrays["u_mean"], arrays["u_scale"])
    with single_thread():
        model = algorithm_class("ppo").load(io.BytesIO(data[MODEL_FILE]), device="cpu")
    try:
        residual_scale = float(manifest.get("imitation", {}).get("residual_scale", 0.0))
    except (AttributeError, TypeError, ValueError) as err:
        raise TrainingError(f"{path}: no imitation agent ({MANIFEST}: residual_scale: {err})") from None
    return ImitatedMPCPolicy(env, model, scales, residual_scale)
