"""Training reinforcement-learning agents on ``StewartPlatform-v1`` with stable-baselines3.

The package, one module per job:

- :mod:`~stewart_env.agents.training.hyperparameters`: rl-baselines3-zoo's YAML configs, read and
  split as rl_zoo3 splits them (``configs/agents/<algo>.yml``, or a shipped config by name);
- :mod:`~stewart_env.agents.training.action_rate`: :class:`ActionRatePenalty`, the training
  batch's penalty on the action's change (a config's ``vec_env_wrapper``), imported where named,
  since it imports stable-baselines3;
- :mod:`~stewart_env.agents.training.precision`: :class:`PrecisionReward`, the training batch's
  reward at the success band's scale (a config's ``vec_env_wrapper``), imported where named;
- :mod:`~stewart_env.agents.training.env_kwargs`: ``--env-kwargs`` and JSON-fit settings;
- :mod:`~stewart_env.agents.training.rundir`: the run directory (manifest, checkpoints, hashes),
  written and read through :mod:`stewart_env.files`;
- :mod:`~stewart_env.agents.training.signals`: SIGINT and SIGTERM while training;
- :mod:`~stewart_env.agents.training.environment`: the training VecEnv and its threads, SB3's
  ``SubprocVecEnv`` with its workers' physics threads sized to the cores;
- :mod:`~stewart_env.agents.training.settings`: :class:`TrainSettings`, a run's request as one
  checked frozen record, and :class:`RunPlan`, the run it resolves to;
- :mod:`~stewart_env.agents.training.callbacks`: the SB3 callbacks (checkpoints and the stop on a
  signal, the timer of collection and learning);
- :mod:`~stewart_env.agents.training.trainer`: :func:`train`;
- :mod:`~stewart_env.agents.training.agent`: :func:`load_agent` and :class:`TrainedAgent`.

stable-baselines3 and torch are imported inside the functions that need them, so that
``stewart-env`` commands that do not train start without loading torch.  The seed bound is the
package's one :data:`stewart_env.validation.MAX_SEED`.
"""

from stewart_env.agents.training.agent import TrainedAgent, load_agent
from stewart_env.agents.training.callbacks import checkpoint_callback, timer_callback
from stewart_env.agents.training.env_kwargs import jsonable, parse_env_kwargs
from stewart_env.agents.training.environment import (
    SizedEnvFactory,
    available_cores,
    make_subprocess_env,
    make_training_env,
    progress_bar_available,
    single_thread,
    worker_threads,
)
from stewart_env.agents.training.errors import TrainingError, TrainingInterrupted, check_rl_installed
from stewart_env.agents.training.hyperparameters import (
    ACTIVATIONS,
    ALGORITHM_NAMES,
    ALGORITHMS,
    CONFIG_DIR,
    MAX_COUNT,
    OFF_POLICY,
    VEC_ENV_WRAPPERS,
    ZOO_EVALUATED_KEYS,
    ZOO_KEYS_HANDLED,
    ZOO_KEYS_ZOO_ONLY,
    ZOO_SCHEDULE_KEYS,
    Hyperparameters,
    algorithm_class,
    check_hyperparameter_names,
    config_path,
    parse_hyperparameters,
    read_hyperparameters,
    shipped_configs,
    vec_env_wrappers,
    zoo_eval,
)
from stewart_env.agents.training.rundir import (
    CHECKPOINT_DIR,
    CHECKPOINT_MANIFEST,
    DEFAULT_KEEP_CHECKPOINTS,
    MANIFEST,
    MAX_AGENT_FILE_BYTES,
    MAX_MANIFEST_BYTES,
    MODEL_FILE,
    PAUSE_IN_CHECKPOINT_ENV,
    REPLAY_BUFFER_FILE,
    VECNORMALIZE_FILE,
    checkpoint_problem,
    log_progress,
    newest_checkpoint,
    read_manifest,
    run_manifest,
    save_agent,
    save_checkpoint,
)
from stewart_env.agents.training.settings import RunPlan, TrainSettings
from stewart_env.agents.training.trainer import TrainResult, rollout_steps, run_changes, train
from stewart_env.registration import ENV_ID
from stewart_env.validation import MAX_SEED

__all__ = [
    "ACTIVATIONS",
    "ALGORITHM_NAMES",
    "ALGORITHMS",
    "CHECKPOINT_DIR",
    "CHECKPOINT_MANIFEST",
    "CONFIG_DIR",
    "DEFAULT_KEEP_CHECKPOINTS",
    "checkpoint_problem",
    "ENV_ID",
    "MANIFEST",
    "MAX_AGENT_FILE_BYTES",
    "MAX_COUNT",
    "MAX_MANIFEST_BYTES",
    "MAX_SEED",
    "MODEL_FILE",
    "OFF_POLICY",
    "PAUSE_IN_CHECKPOINT_ENV",
    "REPLAY_BUFFER_FILE",
    "VECNORMALIZE_FILE",
    "VEC_ENV_WRAPPERS",
    "ZOO_EVALUATED_KEYS",
    "ZOO_KEYS_HANDLED",
    "ZOO_KEYS_ZOO_ONLY",
    "ZOO_SCHEDULE_KEYS",
    "Hyperparameters",
    "RunPlan",
    "SizedEnvFactory",
    "TrainResult",
    "TrainSettings",
    "TrainedAgent",
    "TrainingError",
    "TrainingInterrupted",
    "algorithm_class",
    "available_cores",
    "check_hyperparameter_names",
    "checkpoint_callback",
    "check_rl_installed",
    "config_path",
    "jsonable",
    "load_agent",
    "log_progress",
    "make_subprocess_env",
    "make_training_env",
    "newest_checkpoint",
    "parse_env_kwargs",
    "parse_hyperparameters",
    "progress_bar_available",
    "read_hyperparameters",
    "read_manifest",
    "rollout_steps",
    "run_changes",
    "run_manifest",
    "save_agent",
    "save_checkpoint",
    "shipped_configs",
    "single_thread",
    "timer_callback",
    "train",
    "vec_env_wrappers",
    "worker_threads",
    "zoo_eval",
]
