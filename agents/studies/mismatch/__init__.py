"""Sim-to-sim model mismatch: what a controller loses when it was designed or trained on a
simplified dynamics model of the Stewart platform, as numbers with confidence intervals.

The study is a matrix.  Rows are controllers, each tied to the dynamics model it was built on:

* ``PD + gravity comp. [m]``: the task-space PD law with the holding forces of model ``m``'s
  statics (the only model term it uses);
* ``CT [m]``: the computed-torque controller with internal model ``m`` (its inverse dynamics);
* ``<ALGO> [m]``: RL agents trained on a plant simulated with model ``m``, one per training seed;
* ``<ALGO> [improved + DR]`` (optional): agents trained on the improved model with domain
  randomisation of the inertial and friction parameters (:data:`DEFAULT_RANDOMIZATION`).

The models are the training models and, per simplification, ``improved+cK``: the improved model
with one of the classical model's simplifications C1-C4 switched on.  PD and CT rows exist for
the closed-form models only; an agent can be trained on any model the environment simulates.
Columns are test plants: the environment simulated with each test model (nominal parameters).

Controllers are built on the study's platform, the plants' own.  Each controller platform
(``controller_platforms``, e.g. a platform identified from the plant's data by ``stewart-env
identify``) adds the rows of every training model built (and trained) on it, labelled
``[m @ NAME]`` and run on the same plants; their cost is against the row built on the exact model
and the plants' platform, and for the exact model's structure the share of the classical model's
cost they remove (:data:`SHARE_REMOVED`).

Every cell runs the row's controller on the column's plant over the same seeded episodes (for
each training seed of a learned row) and reports a point estimate with a 95 % stratified
bootstrap interval over seeds and episodes (:mod:`stewart_env.agents.evaluation.statistics`): the success
rate as a mean, every other metric as an interquartile mean (a few failed episodes dominate a
mean).  The cost of a simplification to a controller family is the paired difference, on the
exact (improved) plant, between the family's row built on the simplified model and its row built
on the exact one; it is resolved when its interval excludes zero.  Where the simplified model is
a test plant too, the double difference compares each controller with itself on the two plants
(see :class:`Difference`): the training seeds' own spread cancels in it.

Output in DIR: ``matrix.csv`` (one line per row and test plant; every metric with
``<metric>_ci_low``, ``<metric>_ci_high`` and ``<metric>_n``, the values it rests on),
``matrix.md`` (tables with intervals, the costs and their ranking), ``differences.csv``,
``forest.png`` (every cost with its interval) and ``heatmap_<metric>.png``; trained agents in
``DIR/agents/<name>/seed_<s>/`` and each finished evaluation in ``DIR/cells/`` (a second run with
the same DIR reuses both and runs only what is missing).  ``study.json`` holds the settings that
give the cells their meaning; a second run with other settings is refused.  One command at a time
works on a study: ``mismatch`` holds the lock of DIR (:func:`stewart_env.files.lock_folder`) until
it ends, and a second one on the same DIR is refused at once.  A study's agents belong to it: they
are not shared with another study through a common folder (``DIR/agents`` as a symbolic link is
refused), since a study's finished cells name the hashes of the agents they ran.  A full disk ends
the study with the file it could not write; the finished agents and cells are kept.

Work runs on a backend: ``local`` (in this process, one job after another) or ``ray`` (every
training run and every evaluation is a Ray task requesting :data:`CPUS_PER_JOB` CPUs, on a local
Ray instance or an existing cluster).  Both give the same numbers for the same seeds.  A Ray job
runs its physics batches on as many threads as it was given CPUs; ``physics_threads``
(``--physics-threads N``) sets another count for every job, on either backend.

The package by job: :mod:`.constants` (the study's constants and its error),
:mod:`.settings` (the settings as one checked frozen record, :class:`MismatchSettings`),
:mod:`.backends` (local, Ray), :mod:`.jobs` (what a worker runs), :mod:`.rows` (the controllers
and their agents), :mod:`.cells` (the finished evaluations on disk), :mod:`.study` (the
orchestration, :func:`run_mismatch`), :mod:`.costs` (the simplifications' costs and statistics),
:mod:`.tables` (matrix.md and the CSV files), :mod:`.timing` (the jobs' measured times and
the study's makespan on more machines) and :mod:`.figures` (the PNG figures, drawn only when
asked).  The command line is :mod:`stewart_env.cli.mismatch`.
"""

from stewart_env.agents.studies.mismatch.backends import (
    BackendError,
    LocalBackend,
    RayBackend,
    check_backend,
    make_backend,
    ray_endpoint,
)
from stewart_env.agents.studies.mismatch.cells import cell_path, cell_spec, cell_values, read_cell
from stewart_env.agents.studies.mismatch.constants import (
    AGENT_FILES,
    AGENTS_DIR,
    AUTO_THREADS,
    BACKENDS,
    CELLS_DIR,
    CONTROLLERS,
    CPUS_PER_JOB,
    DEFAULT_CONTROLLERS,
    DEFAULT_RANDOMIZATION,
    DEFAULT_STATISTIC,
    EVAL_SEED_OFFSET,
    FAILURE_THRESHOLD,
    MAX_CELL_BYTES,
    MAX_STEPS,
    QUICK_TIMESTEPS,
    RANKING_METRICS,
    RAY_AUTH_HINT,
    RAY_CONNECT_TIMEOUT,
    RAY_INSTALL_HINT,
    SIMPLIFICATION_TEXT,
    SIMPLIFICATIONS,
    STATISTIC,
    STUDY_FILE,
    TRUE_MODEL,
    MismatchError,
    statistic,
)
from stewart_env.agents.studies.mismatch.costs import (
    PLANNING_BASES,
    per_seed_estimates,
    seeds_needed,
    simplification_costs,
)
from stewart_env.agents.studies.mismatch.figures import forest_figure, heatmap, heatmap_figure, write_figures
from stewart_env.agents.studies.mismatch.jobs import agent_files, evaluate_job, make_policy, train_job
from stewart_env.agents.studies.mismatch.results import (
    COST,
    DOUBLE_DIFFERENCE,
    SHARE_REMOVED,
    Difference,
    MismatchResult,
    Row,
)
from stewart_env.agents.studies.mismatch.rows import (
    build_rows,
    config_env_kwargs,
    finished_agent,
    publish_agent,
    train_agent,
    training_keywords,
)
from stewart_env.agents.studies.mismatch.settings import (
    MismatchSettings,
    check_own_agents,
    check_study,
    closed_form,
    design_models,
)
from stewart_env.agents.studies.mismatch.study import run_jobs, run_mismatch, run_study, summarize, write_outputs
from stewart_env.agents.studies.mismatch.tables import format_interval, markdown, write_tables
from stewart_env.agents.studies.mismatch.timing import JobTimes, makespan, scale_out

__all__ = [
    "AGENTS_DIR",
    "AGENT_FILES",
    "AUTO_THREADS",
    "BACKENDS",
    "CELLS_DIR",
    "COST",
    "CONTROLLERS",
    "CPUS_PER_JOB",
    "DEFAULT_CONTROLLERS",
    "DEFAULT_RANDOMIZATION",
    "DEFAULT_STATISTIC",
    "DOUBLE_DIFFERENCE",
    "EVAL_SEED_OFFSET",
    "FAILURE_THRESHOLD",
    "MAX_CELL_BYTES",
    "MAX_STEPS",
    "PLANNING_BASES",
    "QUICK_TIMESTEPS",
    "RANKING_METRICS",
    "RAY_AUTH_HINT",
    "RAY_CONNECT_TIMEOUT",
    "RAY_INSTALL_HINT",
    "SHARE_REMOVED",
    "SIMPLIFICATIONS",
    "SIMPLIFICATION_TEXT",
    "STATISTIC",
    "STUDY_FILE",
    "TRUE_MODEL",
    "BackendError",
    "Difference",
    "JobTimes",
    "LocalBackend",
    "MismatchError",
    "MismatchResult",
    "MismatchSettings",
    "RayBackend",
    "Row",
    "agent_files",
    "build_rows",
    "cell_path",
    "cell_spec",
    "cell_values",
    "check_backend",
    "check_own_agents",
    "check_study",
    "closed_form",
    "config_env_kwargs",
    "design_models",
    "evaluate_job",
    "finished_agent",
    "forest_figure",
    "format_interval",
    "heatmap",
    "heatmap_figure",
    "make_backend",
    "make_policy",
    "makespan",
    "markdown",
    "per_seed_estimates",
    "publish_agent",
    "ray_endpoint",
    "read_cell",
    "run_jobs",
    "run_mismatch",
    "run_study",
    "scale_out",
    "seeds_needed",
    "simplification_costs",
    "statistic",
    "summarize",
    "train_agent",
    "train_job",
    "training_keywords",
    "write_figures",
    "write_outputs",
    "write_tables",
]
