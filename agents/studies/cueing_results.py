"""The cueing results: PPO with a shipped cueing config against the tuned classical washout on
held-out manoeuvres, with intervals, and the goals each reaches.

The study (``stewart-env cueing-results``) trains one PPO agent per seed with a cueing config
(:data:`PPO_CONFIG` by default, configs/agents/ppo_cueing_residual.yml: PPO as a residual on the
washout, :mod:`stewart_env.agents.training.residual`; or configs/agents/ppo_cueing.yml, PPO
commanding the pose itself; ``task="cueing"``, pose mode) into ``DIR/agents/seed_S`` (or reads
them from a folder of trained agents), then runs the tuned washout (configs/agents/washout.yaml)
and every agent on the same held-out episodes (:data:`MANOEUVRES`, each at the first
``episodes`` of the task's evaluation seeds, side by side in one vector environment:
:class:`~stewart_env.agents.evaluation.cueing.ScheduledEpisodes`).  Per manoeuvre it reports the
perceived specific-force RMS error, the false cues (specific force and angular velocity summed),
the specific-force correlation, the largest stroke use and the share of episodes ended at a limit
(the platform's limits ended it, or a leg reached an end stop: a stroke violation), each with a 95 % stratified bootstrap
interval over seeds and episodes (:func:`~stewart_env.agents.evaluation.statistics.stratified_bootstrap`),
and marks the goals (:data:`GOALS`) reached or not.

What a simplified model costs a cueing agent (the mismatch study's question, asked of cueing):
with ``agent_models`` the study also trains each seed's agent on each of those dynamics models
(``DIR/agents_<model>/seed_S``; the classical model, or the improved one with switches C1-C4) and
runs it on the same held-out episodes of the exact plant (the improved model, as the agents of
``DIR/agents``): per manoeuvre its metrics, and the cost of the model, the paired difference of
its agent's metric minus the exact model's agent's of the same seed on the same episodes
(:func:`~stewart_env.agents.evaluation.statistics.paired_difference`), with its interval.  The
pose mode's inner loop of the cueing configs (inverse kinematics into the leg servos) uses no
dynamics model, and the washout none: the model is the agent's alone.

With ``mpc_previews`` the study also runs the model-predictive cueing baseline
(:class:`~stewart_env.agents.controllers.cueing_mpc.CueingMPCPolicy`, extra ``mpc``) on the same
held-out episodes, once per preview (the task option ``preview``, the samples of the vehicle's
coming motion the environment observes; the other evaluations keep the config's): its rows
``mpc (preview N)`` and its goals against washout.

A finished evaluation (the washout's, the MPC's, or one agent's) is a file with what its numbers depend on
(its spec), published whole, so that a second run into the same folder reuses it and an
interrupted run keeps what it finished.  The study writes ``cueing.md`` (the table),
``results.json`` and, with matplotlib, ``perceived_specific_force.png`` (the vehicle's perceived
specific force against the washout's and the first agent's on the first episode of
:data:`FIGURE_MANOEUVRE`).
"""

from __future__ import annotations

import json
import math
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from stewart_env.agents.controllers.washout import WashoutPolicy, load_washout_params
from stewart_env.agents.evaluation.cueing import ScheduledEpisodes, perceive
from stewart_env.agents.evaluation.statistics import paired_difference, stratified_bootstrap
from stewart_env.errors import UsageError
from stewart_env.files import publish
from stewart_env.validation import integer

__all__ = [
    "FIGURE_MANOEUVRE",
    "GOALS",
    "MANOEUVRES",
    "CueingResultsSettings",
    "goals_reached",
    "main",
    "results_table",
    "run_cueing_results",
]

#: This module's name, as ``python -m`` runs it.
MODULE = "stewart_env.agents.studies.cueing_results"
#: The held-out manoeuvres: a lane change, braking, a flight turn and a sweep.
MANOEUVRES = ("double_lane_change", "braking", "coordinated_turn", "sweep_y")
#: The manoeuvre of the figure.
FIGURE_MANOEUVRE = "braking"
#: The PPO config of the study: PPO as a residual on the tuned washout.
PPO_CONFIG = "ppo_cueing_residual"
#: The washout of the study.
WASHOUT_CONFIG = "washout"
#: The largest preview of the cueing task (its ``preview`` option), samples.
MAX_PREVIEW = 100
#: The exact model: the plant every evaluation runs, and the model of the reference agents.
TRUE_MODEL = "improved"
#: The goals against washout: (metric, how PPO's mean compares with washout's, the factor).
GOALS = (
    ("rms_specific_force_error", "at most", 0.8),  # at least 20 % lower perceived specific-force error
    ("false_cues", "at most", 0.7),  # 30 % fewer false cues
    ("specific_force_correlation", "at least", 1.0),  # a correlation at least washout's
    ("stroke_violations", "none", 0.0),  # no stroke violation
)
#: The table's metrics: title, format.
COLUMNS = {
    "rms_specific_force_error": ("RMS f err. (m/s²)", ".3f"),
    "false_cues": ("false cues", ".1f"),
    "specific_force_correlation": ("corr. f", ".2f"),
    "stroke_use": ("stroke use", ".2f"),
}


@dataclass(frozen=True)
class CueingResultsSettings:
    """What the study runs.

    Attributes:
        seeds: PPO's training seeds.
        timesteps: environment steps per agent (None: the config's n_timesteps).
        episodes: held-out seeds per manoeuvre (the first of the task's evaluation seeds), 1 to 10.
        manoeuvres: the held-out manoeuvres.
        config: PPO's cueing config, a shipped name or a path (a residual one when its entry
            holds ``residual_washout``).
        agent_models: dynamics models other agents are trained on, each seed's agent on each,
            all run on the exact plant (the improved model): the cost of each model to a cueing
            agent.  Names as the environment's ``model`` (e.g. ``"classical"``,
            ``"improved+c1"``); the improved model itself is the reference, not one of them.
        mpc_previews: the previews (task option ``preview``, samples, 0 to 100) at which the
            model-predictive cueing baseline runs, each its own rows; () for none.
    """

    seeds: tuple[int, ...] = (0, 1, 2, 3, 4)
    timesteps: int | None = None
    episodes: int = 3
    manoeuvres: tuple[str, ...] = MANOEUVRES
    config: str = PPO_CONFIG
    agent_models: tuple[str, ...] = ()
    mpc_previews: tuple[int, ...] = ()

    def __post_init__(self) -> None:
        from stewart_env.dynamics.spec import ModelSpec
        from stewart_env.tasks.cueing.motions import EVALUATION_SEEDS, MOTIONS

        names = tuple(ModelSpec.parse(m, "agent_models").name for m in self.agent_models)
        if TRUE_MODEL in names or len(set(names)) != len(names):
            raise UsageError.about(
                "agent_models",
                f"give distinct models other than {TRUE_MODEL!r} (its agents are the reference), got {self.agent_models!r}",
            )
        object.__setattr__(self, "agent_models", names)  # a frozen record sets its checked names once, here

        previews = tuple(integer("mpc_previews", p, 0, MAX_PREVIEW) for p in self.mpc_previews)
        if len(set(previews)) != len(previews):
            raise UsageError.about("mpc_previews", f"give distinct previews, got {self.mpc_previews!r}")
        object.__setattr__(self, "mpc_previews", previews)
        if not self.seeds or len(set(self.seeds)) != len(self.seeds):
            raise UsageError.about("seeds", f"give distinct training seeds, got {self.seeds!r}")
        if not 1 <= self.episodes <= len(EVALUATION_SEEDS):
            raise UsageError.about("episodes", f"must be 1 to {len(EVALUATION_SEEDS)}, got {self.episodes}")
        unknown = [m for m in self.manoeuvres if m not in MOTIONS]
        if unknown or not self.manoeuvres:
            raise UsageError.about("manoeuvres", f"unknown or none: {unknown or self.manoeuvres!r}")
        from stewart_env.agents.training import TrainingError

        try:
            residual, entry = read_config(self.config)
        except TrainingError as err:
            raise UsageError.about("config", str(err)) from None
        if entry.get("env_kwargs", {}).get("action_mode") != "pose":
            raise UsageError.about("config", f"{self.config}: the cueing study needs env_kwargs action_mode: pose")

    @property
    def residual(self) -> bool:
        """Whether the config's agents are residuals on the washout."""
        from stewart_env.agents.training.residual import ResidualSettings

        return isinstance(read_config(self.config)[0], ResidualSettings)

    @property
    def imitation(self) -> bool:
        """Whether the config's agents start from an imitation of the cueing MPC."""
        from stewart_env.agents.training.imitation import ImitationSettings

        return isinstance(read_config(self.config)[0], ImitationSettings)

    @property
    def label(self) -> str:
        """PPO's row label in the table."""
        from stewart_env.agents.training.imitation import ImitationSettings

        special = read_config(self.config)[0]
        if isinstance(special, ImitationSettings):
            return "ppo (residual on the MPC)" if special.residual else "ppo (from the MPC's imitation)"
        return "ppo" if special is None else "ppo (residual on washout)"

    def held_out(self) -> list[tuple[str, int]]:
        """The held-out (motion, seed) pairs, manoeuvre by manoeuvre."""
        from stewart_env.tasks.cueing.motions import EVALUATION_SEEDS

        return [(m, int(s)) for m in self.manoeuvres for s in EVALUATION_SEEDS[: self.episodes]]


def read_config(config: str):
    """A cueing config's own settings (a residual's on the washout, an imitation's of the MPC, or
    None: PPO commands the pose itself) and its entry without them, as SB3's parser reads it.

    Args:
        config: a shipped config's name or a path.

    Returns:
        (the ResidualSettings, ImitationSettings or None, the entry).

    Raises:
        TrainingError: no such config, or bad residual or imitation settings.
    """
    from stewart_env.agents.training.errors import TrainingError
    from stewart_env.agents.training.hyperparameters import parse_hyperparameters, read_hyperparameters
    from stewart_env.agents.training.imitation import IMITATION_KEY, RESIDUAL_MPC_KEY, imitation_settings
    from stewart_env.agents.training.residual import RESIDUAL_KEY, residual_settings

    entry = read_hyperparameters("ppo", config)
    special = None
    given = [k for k in (RESIDUAL_KEY, IMITATION_KEY, RESIDUAL_MPC_KEY) if k in entry]
    if len(given) > 1:
        raise TrainingError(f"{config}: give one of {', '.join(given)}, not {len(given)}")
    if RESIDUAL_KEY in entry:
        special, entry = residual_settings(entry)
    elif given:
        special, entry = imitation_settings(entry)
    parse_hyperparameters("ppo", entry)  # its names and values checked before any work
    return special, entry


def _env_kwargs(config: str) -> dict[str, Any]:
    """The PPO config's environment keywords, which every evaluation uses (the washout reads its
    parts by name, so the preview does not change it); no time limit: each episode runs to its end."""
    kwargs = dict(read_config(config)[1].get("env_kwargs") or {})
    kwargs.pop("max_episode_steps", None)
    options = dict(kwargs.get("task_options", {}))
    options.pop("training_seeds", None)
    kwargs["task_options"] = options
    return kwargs


def _evaluation_spec(settings: CueingResultsSettings, policy: str, seed: int | None, timesteps: int | None) -> dict:
    return {
        "policy": policy,
        "seed": seed,
        "timesteps": timesteps,
        "episodes": settings.held_out(),
        "env_kwargs": _env_kwargs(settings.config),
    }


def _read(path: Path, spec: dict) -> dict | None:
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return data if data.get("spec") == json.loads(json.dumps(spec)) else None


def _evaluate(
    out: Path, settings: CueingResultsSettings, name: str, policy, spec: dict, figure: bool
) -> dict[str, Any]:
    """One policy's metrics per episode (reused from ``out/evaluations/name.json`` when its spec matches)."""
    path = out / "evaluations" / f"{name}.json"
    found = _read(path, spec)
    if found is not None:
        return found
    runner = ScheduledEpisodes(settings.held_out(), spec["env_kwargs"])
    try:
        rows = runner.run(policy, traces=figure)
        dt = runner.dt
    finally:
        runner.close()
    trace = None
    if figure:
        first = next(i for i, (m, _) in enumerate(settings.held_out()) if m == FIGURE_MANOEUVRE)
        steps = rows[first]["traces"]
        vehicle, _ = perceive(steps["vehicle_specific_force"], steps["vehicle_angular_velocity"], dt)
        head, _ = perceive(steps["head_specific_force"], steps["head_angular_velocity"], dt)
        trace = {"dt": dt, "vehicle": vehicle.tolist(), "platform": head.tolist()}
    for row in rows:
        row.pop("traces", None)
    data = {"spec": spec, "episodes": rows, "figure": trace}
    path.parent.mkdir(parents=True, exist_ok=True)
    publish(path, json.dumps(data, allow_nan=True))
    return json.loads(json.dumps(data))


def _evaluate_mpc(out: Path, settings: CueingResultsSettings, preview: int) -> dict[str, Any]:
    """The model-predictive cueing baseline's metrics per episode, with the task's ``preview`` set."""
    from dataclasses import asdict

    from stewart_env.agents.controllers.cueing_mpc import CueingMPCParams, CueingMPCPolicy

    params = CueingMPCParams()
    spec = {**_evaluation_spec(settings, "mpc", None, None), "params": asdict(params)}
    spec["env_kwargs"] = {
        **spec["env_kwargs"],
        "task_options": {**spec["env_kwargs"]["task_options"], "preview": preview},
    }
    return _evaluate(out, settings, f"mpc_preview_{preview}", lambda env: CueingMPCPolicy(env, params), spec, False)


def _timesteps(settings: CueingResultsSettings) -> int:
    if settings.timesteps is not None:
        return settings.timesteps
    return int(float(read_config(settings.config)[1]["n_timesteps"]))


def agents_folder(root: Path, model: str = TRUE_MODEL) -> Path:
    """The folder of the agents trained on ``model`` in a study's folder: ``agents`` for the
    exact model, ``agents_<model>`` for another.

    Args:
        root: the study's folder.
        model: the agents' dynamics model (a canonical name).

    Returns:
        The folder, whose agents are ``seed_S``.
    """
    return root / ("agents" if model == TRUE_MODEL else f"agents_{model}")


def _train(
    out: Path, agents: Path | None, settings: CueingResultsSettings, seed: int, progress: bool, model: str = TRUE_MODEL
) -> Path | None:
    """The agent of ``seed`` trained on ``model``: trained into ``out/agents/seed_S`` (or
    ``agents_<model>``; continued if stopped; a residual agent trained again), or read from
    ``agents`` (its ``seed_S`` for the exact model, the sibling ``agents_<model>/seed_S`` for another)."""
    from stewart_env.agents.studies.mismatch.rows import finished_agent, train_agent

    if agents is not None:
        folder = (agents if model == TRUE_MODEL else agents_folder(agents.parent, model)) / f"seed_{seed}"
        return folder if folder.is_dir() else None
    folder = agents_folder(out, model) / f"seed_{seed}"
    timesteps = _timesteps(settings)
    if settings.residual or settings.imitation:
        from stewart_env.agents.training import imitation, residual

        manifest_file = residual.MANIFEST if settings.residual else imitation.MANIFEST
        train = residual.train_residual if settings.residual else imitation.train_imitation
        try:
            done = json.loads((folder / manifest_file).read_text())
        except (OSError, ValueError):
            done = {}
        wanted = {"config": str(settings.config), "seed": seed}
        trained_on = (done.get("env_kwargs") or {}).get("model", TRUE_MODEL)
        if (
            {k: done.get(k) for k in wanted} != wanted
            or trained_on != model
            or done.get("num_timesteps", 0) < timesteps
        ):
            env_kwargs = None if model == TRUE_MODEL else {"model": model}
            train(folder, settings.config, seed, timesteps, env_kwargs=env_kwargs, progress_bar=progress)
        return folder
    kwargs = config_env_kwargs_of_training(settings.config)
    if model != TRUE_MODEL:
        kwargs = {**kwargs, "model": model}
    if not finished_agent(folder, "ppo", seed, kwargs):
        training = {"algo": "ppo", "task": "cueing", "seed": seed, "config": settings.config}
        if model != TRUE_MODEL:
            training["model"] = model
        train_agent(folder, training, timesteps, progress)
    return folder


def config_env_kwargs_of_training(config: str = PPO_CONFIG) -> dict[str, Any]:
    """The environment keywords a trained agent's run.json records (the config's, with the task).

    Args:
        config: the PPO config.

    Returns:
        The keywords.
    """
    from stewart_env.agents.studies.mismatch.rows import config_env_kwargs

    return {**config_env_kwargs("ppo", config), "task": "cueing"}


def _agent(folder: Path, settings: CueingResultsSettings):
    """(the agent's policy or its factory, its files' sha256, its training's record)."""
    if settings.residual or settings.imitation:
        from stewart_env.agents.training import imitation, residual

        manifest_file = residual.MANIFEST if settings.residual else imitation.MANIFEST
        load = residual.load_residual if settings.residual else imitation.load_imitation
        manifest = json.loads((folder / manifest_file).read_text())
        keys = ("num_timesteps", "cpu_seconds", "wall_seconds", "episode_endings", "cpu_seconds_by_stage")
        training = {k: manifest[k] for k in keys if k in manifest}
        return (lambda env: load(folder, env)), manifest["files"], training
    from stewart_env.agents.training import load_agent

    manifest = json.loads((folder / "run.json").read_text())
    training = {"num_timesteps": manifest.get("num_timesteps"), "wall_seconds": manifest.get("wall_time")}
    return load_agent(folder), manifest.get("files"), training


def run_cueing_results(
    out, settings: CueingResultsSettings | None = None, agents=None, progress: bool = True
) -> dict[str, Any]:
    """Run the study (module docstring) into ``out``.

    Args:
        out: the study's folder (created; its finished evaluations are reused).
        settings: what to run (default :class:`CueingResultsSettings`).
        agents: a folder of trained agents (``seed_S``), read only; None: train them into ``out/agents``.
        progress: show the training's progress bars.

    Returns:
        The results: per manoeuvre and policy the intervals, the goals, the seeds evaluated.

    Raises:
        UsageError: bad settings.
    """
    settings = settings or CueingResultsSettings()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    washout = load_washout_params(WASHOUT_CONFIG)
    evaluations = {
        "washout": _evaluate(
            out,
            settings,
            "washout",
            lambda env: WashoutPolicy(env, washout),
            {**_evaluation_spec(settings, "washout", None, None), "params": washout.as_dict()},
            True,
        )
    }
    mpc = {preview: _evaluate_mpc(out, settings, preview) for preview in settings.mpc_previews}
    ppo: dict[int, dict] = {}
    training: dict[int, dict] = {}
    by_model: dict[str, dict[int, dict]] = {}
    for model in (TRUE_MODEL, *settings.agent_models):
        evaluated = ppo if model == TRUE_MODEL else by_model.setdefault(model, {})
        for seed in settings.seeds:
            folder = _train(out, None if agents is None else Path(agents), settings, seed, progress, model)
            if folder is None:
                continue
            policy, files, record = _agent(folder, settings)
            spec = _evaluation_spec(settings, "ppo", seed, settings.timesteps)
            spec["agent"] = files
            spec["config"] = str(settings.config)
            if model == TRUE_MODEL:
                training[seed] = record
                name, figure = f"ppo_seed_{seed}", seed == settings.seeds[0]
            else:
                spec["agent_model"] = model
                name, figure = f"ppo_{model}_seed_{seed}", False
            evaluated[seed] = _evaluate(out, settings, name, policy, spec, figure)
    results = summarize(settings, evaluations["washout"], ppo, by_model, mpc)
    results["training"] = {str(seed): record for seed, record in training.items()}
    publish(out / "results.json", json.dumps(results, indent=1, allow_nan=True))
    publish(out / "cueing.md", results_table(results) + "\n")
    trace_ppo = next((e["figure"] for e in ppo.values() if e.get("figure")), None)
    _figure(out / "perceived_specific_force.png", evaluations["washout"]["figure"], trace_ppo, settings.label)
    return results


def _values(evaluation: dict, manoeuvre: str, held_out: list[tuple[str, int]], metric: str) -> list[float]:
    rows = [r for (m, _), r in zip(held_out, evaluation["episodes"]) if m == manoeuvre]
    if metric == "false_cues":
        return [r["false_specific_force_cues"] + r["false_angular_velocity_cues"] for r in rows]
    if metric == "stroke_violations":
        return [float(r["stroke_use"] >= 1.0 or r["failed"] > 0.0) for r in rows]
    return [float(r[metric]) for r in rows]


def summarize(
    settings: CueingResultsSettings,
    washout: dict,
    ppo: dict[int, dict],
    by_model: dict[str, dict[int, dict]] | None = None,
    mpc: dict[int, dict] | None = None,
) -> dict[str, Any]:
    """The intervals and goals of the study's evaluations.

    Args:
        settings: the study's settings.
        washout: the washout's evaluation.
        ppo: training seed -> the agent's evaluation (agents trained on the exact model).
        by_model: dynamics model -> training seed -> the evaluation of the agent trained on that
            model (run on the exact plant).
        mpc: preview -> the model-predictive cueing baseline's evaluation at that preview.

    Returns:
        ``{"seeds": [...], "episodes": k, "agent_models": {model: seeds}, "manoeuvres": {name:
        {"washout": {metric: interval}, "ppo": {...}, "goals": {goal: bool}, "models": {model:
        {"ppo": {metric: interval}, "cost": {metric: interval}, "seeds": [...]}}}}}``, an interval
        [estimate, low, high], and per manoeuvre ``"mpc": {preview: {"intervals": {...}, "goals":
        {...}}}`` with ``mpc``; a model's cost is its agents' metric minus the exact model's agents'
        of the same seeds on the same episodes (the seeds both have).
    """
    held_out = settings.held_out()
    metrics = (*COLUMNS, "stroke_violations")
    table: dict[str, Any] = {}
    for manoeuvre in settings.manoeuvres:

        def cell_of(evaluations: dict[int, dict], seeds, manoeuvre=manoeuvre) -> dict[str, np.ndarray]:
            return {m: np.array([_values(evaluations[s], manoeuvre, held_out, m) for s in seeds]) for m in metrics}

        entry: dict[str, Any] = {"washout": _intervals(cell_of({0: washout}, [0]))}
        washout_means = {m: v[0] for m, v in entry["washout"].items()}
        for preview, evaluation in (mpc or {}).items():
            intervals = _intervals(cell_of({0: evaluation}, [0]))
            entry.setdefault("mpc", {})[str(preview)] = {
                "intervals": intervals,
                "goals": goals_reached(washout_means, {m: v[0] for m, v in intervals.items()}),
            }
        if ppo:
            entry["ppo"] = _intervals(cell_of(ppo, list(ppo)))
            entry["goals"] = goals_reached(
                {m: v[0] for m, v in entry["washout"].items()}, {m: v[0] for m, v in entry["ppo"].items()}
            )
        for model, evaluations in (by_model or {}).items():
            shared = [s for s in ppo if s in evaluations]
            if not shared:
                continue
            own, reference = cell_of(evaluations, shared), cell_of(ppo, shared)
            entry.setdefault("models", {})[model] = {
                "ppo": _intervals(cell_of(evaluations, list(evaluations))),
                "cost": {m: _as_list(paired_difference(own[m], reference[m])) for m in metrics},
                "seeds": shared,
            }
        table[manoeuvre] = entry
    return {
        "seeds": sorted(ppo),
        "episodes": settings.episodes,
        "config": str(settings.config),
        "label": settings.label,
        "agent_models": {model: sorted(e) for model, e in (by_model or {}).items()},
        "mpc_previews": sorted(mpc or {}),
        "manoeuvres": table,
    }


def _as_list(interval) -> list[float]:
    return [interval.estimate, interval.low, interval.high]


def _intervals(cell: dict[str, np.ndarray]) -> dict[str, list[float]]:
    """Each metric's stratified bootstrap interval over a cell (seeds, episodes)."""
    return {m: _as_list(stratified_bootstrap(values)) for m, values in cell.items()}


def goals_reached(washout: dict[str, float], ppo: dict[str, float]) -> dict[str, bool]:
    """Whether PPO's means reach each of :data:`GOALS` against washout's.

    Args:
        washout: metric -> washout's mean.
        ppo: metric -> PPO's mean.

    Returns:
        metric -> reached.
    """
    reached = {}
    for metric, relation, factor in GOALS:
        if relation == "none":
            reached[metric] = bool(ppo[metric] == 0.0)
        elif relation == "at most":
            reached[metric] = bool(ppo[metric] <= factor * washout[metric])
        else:
            reached[metric] = bool(ppo[metric] >= factor * washout[metric])
    return reached


def _interval(values: Sequence[float], spec: str) -> str:
    estimate, low, high = values
    if not math.isfinite(estimate):
        return "n/a"
    return f"{estimate:{spec}} [{low:{spec}}, {high:{spec}}]"


def results_table(results: dict[str, Any]) -> str:
    """The study's Markdown table: per manoeuvre and policy the metrics with 95 % intervals, and the goals.

    Args:
        results: :func:`run_cueing_results`'s results.

    Returns:
        The Markdown text.
    """
    head = ["manoeuvre", "policy", *(title for title, _ in COLUMNS.values()), "ended at a limit"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    goal_lines = [
        "| manoeuvre | f error -20 % | false cues -30 % | corr. f >= washout | no stroke violation |",
        "|---|---|---|---|---|",
    ]
    mpc_goal_lines = [
        "| manoeuvre | policy | f error -20 % | false cues -30 % | corr. f >= washout | no stroke violation |",
        "|---|---|---|---|---|---|",
    ]
    cost_head = ["manoeuvre", "agents trained on", *(title for title, _ in COLUMNS.values()), "ended at a limit"]
    cost_lines = ["| " + " | ".join(cost_head) + " |", "|" + "---|" * len(cost_head)]
    for manoeuvre, entry in results["manoeuvres"].items():
        rows = [("washout", entry["washout"])]
        rows += [(f"mpc (preview {p})", e["intervals"]) for p, e in entry.get("mpc", {}).items()]
        rows += [("ppo", entry["ppo"])] if "ppo" in entry else []
        rows += [(f"ppo, trained on {model}", e["ppo"]) for model, e in entry.get("models", {}).items()]
        for label, intervals in rows:
            cells = [_interval(intervals[m], spec) for m, (_, spec) in COLUMNS.items()]
            cells.append(_interval(intervals["stroke_violations"], ".2f"))
            shown = results.get("label", "ppo") + label[3:] if label.startswith("ppo") else label
            lines.append(f"| {manoeuvre} | {shown} | " + " | ".join(cells) + " |")
        for model, e in entry.get("models", {}).items():
            cells = [_interval(e["cost"][m], "+" + spec) for m, (_, spec) in COLUMNS.items()]
            cells.append(_interval(e["cost"]["stroke_violations"], "+.2f"))
            cost_lines.append(f"| {manoeuvre} | {model} | " + " | ".join(cells) + " |")
        if "goals" in entry:
            marks = ["reached" if entry["goals"][m] else "not reached" for m, _, _ in GOALS]
            goal_lines.append(f"| {manoeuvre} | " + " | ".join(marks) + " |")
        for preview, e in entry.get("mpc", {}).items():
            marks = ["reached" if e["goals"][m] else "not reached" for m, _, _ in GOALS]
            mpc_goal_lines.append(f"| {manoeuvre} | mpc (preview {preview}) | " + " | ".join(marks) + " |")
    seeds = results["seeds"]
    note = (
        f"PPO ({results.get('config', PPO_CONFIG)}): {len(seeds)} training seed(s) ({', '.join(map(str, seeds)) or 'none'}), "
        f"{results['episodes']} held-out episode(s) per manoeuvre; 95 % stratified bootstrap intervals."
    )
    text = "\n".join(lines) + "\n\n" + note
    if len(goal_lines) > 2:
        text += "\n\n" + "\n".join(goal_lines)
    if len(mpc_goal_lines) > 2:
        text += (
            "\n\nThe model-predictive cueing baseline (CueingMPCPolicy, its default parameters) against washout, "
            "at each preview of the vehicle's coming motion (samples of the control step); "
            "its intervals over the held-out episodes.\n\n" + "\n".join(mpc_goal_lines)
        )
    if len(cost_lines) > 2:
        text += (
            "\n\nWhat a model costs the cueing agent: the metric of the agents trained on it minus that of the "
            f"agents trained on the {TRUE_MODEL} model, the same seeds on the same episodes of the {TRUE_MODEL} "
            "plant (paired 95 % intervals; a higher error, more false cues, a lower correlation are worse).\n\n"
            + "\n".join(cost_lines)
        )
    return text


def _figure(path: Path, washout: dict | None, ppo: dict | None, label: str = "ppo") -> None:
    """The perceived specific force's x over time: the vehicle's, the washout's and PPO's."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:  # the figure is optional
        return
    if washout is None:
        return
    fig, ax = plt.subplots(figsize=(7, 3.2))
    dt = washout["dt"]
    vehicle = np.asarray(washout["vehicle"])
    t = dt * np.arange(len(vehicle))
    ax.plot(t, vehicle[:, 0], "k", label="vehicle")
    w = np.asarray(washout["platform"])
    ax.plot(dt * np.arange(len(w)), w[:, 0], label="washout")
    if ppo is not None:
        p = np.asarray(ppo["platform"])
        ax.plot(dt * np.arange(len(p)), p[:, 0], label=label.replace("ppo", "PPO"))
    ax.set_xlabel("time (s)")
    ax.set_ylabel("perceived f_x (m/s²)")
    ax.set_title(f"{FIGURE_MANOEUVRE}, held-out seed")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m stewart_env.agents.studies.cueing_results OUT``: the study with its defaults.

    Args:
        argv: the command line's arguments after the module (default sys.argv's): OUT.

    Returns:
        The exit status: 0, or 2 with a one-line usage error.
    """
    argv = sys.argv[1:] if argv is None else list(argv)
    if len(argv) != 1 or argv[0].startswith("-"):
        print(f"usage: python -m {MODULE} OUT  (got {' '.join(argv)})", file=sys.stderr)
        return 2
    results = run_cueing_results(argv[0])
    print(results_table(results))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
