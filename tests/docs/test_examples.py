"""The runnable examples (``Examples:`` sections with ``>>>`` lines) of the main entry points run
as written, and every entry point listed here has one.

Each object's own docstring is run with :mod:`doctest` (``ELLIPSIS | NORMALIZE_WHITESPACE``),
without recursing into its members: a method with an example is listed by its own name.
"""

from __future__ import annotations

import doctest
import importlib
import pkgutil

import pytest

#: The main entry points, by dotted name: each must carry an example that runs.
ENTRY_POINTS = [
    "stewart_env.make_dynamics",
    "stewart_env.ModelSpec",
    "stewart_env.errors.UsageError",
    "stewart_env.validation.Interval",
    "stewart_env.Dynamics.forward",
    "stewart_env.Dynamics.inverse",
    "stewart_env.Workspace",
    "stewart_env.rollout",
    "stewart_env.params.load_platform",
    "stewart_env.params.PlatformParams",
    "stewart_env.envs.StewartPlatformEnv",
    "stewart_env.envs.StewartPlatformVectorEnv",
    pytest.param("stewart_env.envs.StewartPlatformSB3VecEnv", marks=pytest.mark.extra("rl")),
    "stewart_env.envs.EnvConfig.of",
    "stewart_env.envs.holding_action",
    "stewart_env.tasks.make_task",
    "stewart_env.leg_kinematics",
    "stewart_env.forward_kinematics",
    "stewart_env.rpy_to_matrix",
    "stewart_env.randomization.Randomization",
    "stewart_env.validation.real",
    "stewart_env.files.publish",
    "agents.controllers.pd.TaskSpacePD",
    "agents.controllers.computed_torque.ComputedTorque",
    "agents.controllers.pd.zoh_pd_gains",
    "agents.controllers.pd.PDPolicy",
    "agents.controllers.computed_torque.preview_acceleration",
    "agents.evaluation.statistics.iqm",
    "agents.evaluation.statistics.paired_difference",
    "agents.evaluation.statistics.stratified_bootstrap",
    pytest.param("stewart_env.mujoco.MujocoPlant", marks=pytest.mark.extra("mujoco")),
    pytest.param("stewart_env.mujoco.to_mjcf", marks=pytest.mark.extra("mujoco")),
    pytest.param("stewart_env.mujoco.platform_acceleration", marks=pytest.mark.extra("mujoco")),
    pytest.param("stewart_env.dynamics.symbolic.forward_dynamics_function", marks=pytest.mark.extra("casadi")),
]

OPTIONS = doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE


def resolve(dotted: str):
    """The object a dotted name names: the longest importable module prefix, then attributes."""
    parts = dotted.split(".")
    for split in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:split]))
        except ModuleNotFoundError:
            continue
        for attribute in parts[split:]:
            obj = getattr(obj, attribute)
        return obj
    raise ImportError(dotted)


@pytest.mark.parametrize("name", ENTRY_POINTS)
def test_the_example_runs(name):
    tests = [test for test in doctest.DocTestFinder(recurse=False).find(resolve(name), name, globs={}) if test.examples]
    assert tests, f"{name} has no example (an Examples: section with >>> lines)"
    runner = doctest.DocTestRunner(optionflags=OPTIONS)
    for test in tests:
        runner.run(test)
    result = runner.summarize(verbose=False)
    assert result.failed == 0, (
        f"{name}: {result.failed} of {result.attempted} example lines failed (see the output above)"
    )


#: Modules whose examples are listed above: the physics, the environments, the tasks, the MuJoCo
#: twin and the baseline controllers (training, studies and commands keep their own lists).
LISTED_PACKAGES = (
    "stewart_env.dynamics",
    "stewart_env.envs",
    "stewart_env.tasks",
    "stewart_env.params",
    "stewart_env.mujoco",
)
LISTED_MODULES = (
    "stewart_env",
    "stewart_env.integrate",
    "stewart_env.kinematics",
    "stewart_env.rotations",
    "stewart_env.state",
    "stewart_env.randomization",
    "stewart_env.validation",
    "stewart_env.files",
    "stewart_env.errors",
    "agents.controllers.pd",
    "agents.controllers.computed_torque",
    "agents.evaluation.statistics",
)


def examples_in(modules) -> dict[str, str]:
    """{docstring: name} of every docstring with an example in ``modules`` and their members, by its
    text: doctest's line of a function shown under its package (``__module__`` reassigned) is a
    guess in the package's ``__init__.py``, which moves when the defining module's lines do."""
    return {
        test.docstring: test.name
        for module in modules
        for test in doctest.DocTestFinder().find(module)
        if test.examples
    }


@pytest.mark.extra("rl")  # the scan imports every public module, the SB3 vector env's too
def test_every_example_of_the_public_modules_is_listed():
    modules = [importlib.import_module(name) for name in LISTED_MODULES]
    for package in LISTED_PACKAGES:
        root = importlib.import_module(package)
        modules += [root] + [
            importlib.import_module(info.name)
            for info in pkgutil.walk_packages(root.__path__, package + ".")
            if not info.name.endswith(("__main__", ".cli"))
        ]
    listed = examples_in(resolve(getattr(entry, "values", (entry,))[0]) for entry in ENTRY_POINTS)
    unlisted = sorted(name for docstring, name in examples_in(modules).items() if docstring not in listed)
    assert not unlisted, f"examples not run by this test (add their objects to ENTRY_POINTS): {sorted(unlisted)}"
