"""The package's layers import one way: core <- physics <- tasks <- envs <- agents <- cli.

The core (``stewart_env._core``, the compiled extension, and ``stewart_env.errors``) is a leaf:
every layer may import it and it imports nothing else of the package.
The physics (parameters, kinematics, dynamics, integration, the MuJoCo twin) knows no task and no
environment; a task knows no integrator; the environment knows no agent; agents reach the rest of
the package through public names only.  Read from the source with ``ast``, so a lazy import inside
a function counts as much as one at the top.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

# module (dotted, as installed) -> layer; a package name covers its modules
LAYERS = {
    "stewart_env._core": "core",
    "stewart_env.errors": "core",
    "stewart_env.validation": "physics",
    "stewart_env.files": "physics",
    "stewart_env.extras": "physics",
    "stewart_env.state": "physics",
    "stewart_env.rotations": "physics",
    "stewart_env.params": "physics",
    "stewart_env.randomization": "physics",
    "stewart_env.kinematics": "physics",
    "stewart_env.actuators": "physics",
    "stewart_env.dynamics": "physics",
    "stewart_env.integrate": "physics",
    "stewart_env.progress": "physics",
    "stewart_env.mujoco": "physics",
    "stewart_env.identification": "physics",
    "stewart_env.tasks": "tasks",
    "stewart_env.envs": "envs",
    "stewart_env.registration": "envs",
    "stewart_env.agents": "agents",
    "stewart_env.configs": "agents",
    # the benchmark times the environments and the twin as a user does; nothing below imports it
    "stewart_env.benchmarks": "agents",
    "stewart_env.cli": "cli",
    # `python -m stewart_env` and `python -m stewart_env.mujoco`: entry points into the command line
    "stewart_env.__main__": "cli",
    "stewart_env.mujoco.__main__": "cli",
}
# the package's face re-exports the physics API and registers the environment with Gymnasium
PACKAGE = "stewart_env"
ORDER = ("core", "physics", "tasks", "envs", "agents", "cli")
OWN_PARSERS = ()
# the integrator: a task gets the state it is given and never advances it
INTEGRATOR = ("stewart_env.integrate", "stewart_env.dynamics.rk4")


def layer_of(module: str) -> str | None:
    if module == PACKAGE:
        return "envs"
    best = max((name for name in LAYERS if module == name or module.startswith(name + ".")), key=len, default=None)
    return LAYERS.get(best)


def source_files() -> list[tuple[str, Path]]:
    """(dotted module name, path) of every module of the package, agents included."""
    found = []
    for folder, package in ((ROOT / "stewart_env", "stewart_env"), (ROOT / "agents", "stewart_env.agents")):
        for path in sorted(folder.rglob("*.py")):
            parts = path.relative_to(folder).with_suffix("").parts
            name = ".".join((package, *parts))
            found.append((name.removesuffix(".__init__"), path))
    return found


def folder_of(package: str) -> Path:
    """The source folder of a package of the project (``agents`` and ``configs`` sit at the top)."""
    parts = package.split(".")[1:]
    if parts and parts[0] in ("agents", "configs"):
        return ROOT.joinpath(*parts)
    return ROOT.joinpath(PACKAGE, *parts)


def imports(path: Path) -> list[tuple[str, list[str], int]]:
    """(module, imported names, line) of every ``import stewart_env...`` in the file."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out += [(a.name, [], node.lineno) for a in node.names if a.name.startswith("stewart_env")]
        elif isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("stewart_env"):
            names = [a.name for a in node.names]
            # `from stewart_env import mujoco` imports the module stewart_env.mujoco, not the package
            folder = folder_of(node.module)
            submodules = [n for n in names if (folder / f"{n}.py").exists() or (folder / n).is_dir()]
            out += [(f"{node.module}.{n}", [], node.lineno) for n in submodules]
            if len(submodules) < len(names):
                out.append((node.module, [n for n in names if n not in submodules], node.lineno))
    return out


MODULES = source_files()


def test_every_module_has_a_layer():
    assert len(MODULES) > 30, "the package's modules were not found"
    assert [name for name, _ in MODULES if layer_of(name) is None] == []


@pytest.mark.parametrize("name,path", MODULES, ids=[name for name, _ in MODULES])
def test_imports_run_one_way(name, path):
    own = ORDER.index(layer_of(name))
    upward = [
        f"line {line}: {module} ({layer_of(module)})"
        for module, _, line in imports(path)
        if layer_of(module) and ORDER.index(layer_of(module)) > own
    ]
    assert upward == [], f"{name} ({layer_of(name)}) imports a layer above it"


@pytest.mark.parametrize(
    "name,path",
    [m for m in MODULES if layer_of(m[0]) == "tasks"],
    ids=[n for n, _ in MODULES if layer_of(n) == "tasks"],
)
def test_tasks_import_no_integrator(name, path):
    assert [m for m, _, _ in imports(path) if m.startswith(INTEGRATOR)] == []


@pytest.mark.parametrize(
    "name,path",
    [m for m in MODULES if layer_of(m[0]) == "agents"],
    ids=[n for n, _ in MODULES if layer_of(n) == "agents"],
)
def test_agents_use_public_names_of_the_package(name, path):
    private = [
        f"line {line}: {', '.join(n for n in names if n.startswith('_'))} from {module}"
        for module, names, line in imports(path)
        if layer_of(module) != "agents" and any(n.startswith("_") for n in names)
    ]
    assert private == []


# The parameters are the physics' lowest floor: values, their checks, the config reader and the
# shipped configs. The models are built on them (a check that needs the kernels runs where a
# platform becomes a model), never the other way round.
PARAMETERS = "stewart_env.params"
ABOVE_PARAMETERS = (
    "stewart_env.dynamics",
    "stewart_env.kinematics",
    "stewart_env.integrate",
    "stewart_env.randomization",
    "stewart_env.mujoco",
    "stewart_env.tasks",
    "stewart_env.envs",
)


def imports_above_the_parameters(path: Path) -> list[str]:
    """``line n: module`` of every import of a module the parameters must not know."""
    return [
        f"line {line}: {module}"
        for module, _, line in imports(path)
        if module == PACKAGE or module.startswith(ABOVE_PARAMETERS)
    ]


def test_the_parameters_import_no_model_task_or_environment():
    modules = [(name, path) for name, path in MODULES if name == PARAMETERS or name.startswith(PARAMETERS + ".")]
    assert len(modules) >= 5, "the parameter package's modules were not found"
    assert [f"{name} {hit}" for name, path in modules for hit in imports_above_the_parameters(path)] == []


def library_imports(path: Path) -> list[tuple[str, int]]:
    """(module, line) of every import of a module outside the package (``import x.y``, ``from x import``)."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out += [(a.name, node.lineno) for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
            out.append((node.module, node.lineno))
    return [(m, line) for m, line in out if not m.startswith("stewart_env")]


# The MuJoCo library is reached through one module; the environments reach the integrator and the
# twin through their plant (stewart_env.envs.plant), chosen once from the configuration.
MUJOCO_LIBRARY = "stewart_env.mujoco.library"
PLANT = "stewart_env.envs.plant"


def test_only_the_twins_library_module_imports_mujoco():
    found = [
        f"{name} line {line}: {module}"
        for name, path in MODULES
        for module, line in library_imports(path)
        if module.split(".")[0] == "mujoco" and name != MUJOCO_LIBRARY
    ]
    assert found == [], "import mujoco through stewart_env.mujoco (its library module)"


@pytest.mark.parametrize("simulator", ["stewart_env.mujoco", *INTEGRATOR])
def test_the_environments_reach_a_simulator_only_through_their_plant(simulator):
    envs = [(name, path) for name, path in MODULES if name.startswith("stewart_env.envs") and name != PLANT]
    assert len(envs) > 5
    found = [
        f"{name} line {line}: {module}"
        for name, path in envs
        for module, _, line in imports(path)
        if module == simulator or module.startswith(simulator + ".")
    ]
    assert found == []


# The mismatch study's work modules; its command line (argparse) is stewart_env.cli.mismatch.
MISMATCH = [(name, path) for name, path in MODULES if name.startswith("stewart_env.agents.studies.mismatch")]


@pytest.mark.parametrize("name,path", MISMATCH, ids=[name for name, _ in MISMATCH])
def test_the_mismatch_study_s_work_modules_import_no_argparse(name, path):
    assert len(MISMATCH) > 5, "the study's modules were not found"
    assert [
        f"line {line}: {module}" for module, line in library_imports(path) if module.split(".")[0] == "argparse"
    ] == []
    assert [
        f"line {line}: {module}" for module, _, line in imports(path) if module.startswith("stewart_env.cli")
    ] == [], "argparse types belong to the command line"


def test_the_core_imports_nothing_of_the_package_but_its_errors():
    core = [(name, path) for name, path in MODULES if layer_of(name) == "core"]
    assert {name for name, _ in core} == {"stewart_env._core", "stewart_env.errors"}
    found = [
        f"{name} line {line}: {module}"
        for name, path in core
        for module, _, line in imports(path)
        if layer_of(module) != "core" or module == PACKAGE
    ]
    assert found == []


def import_graph(modules: list[tuple[str, Path]]) -> dict[str, set[str]]:
    """module -> the package's modules its import runs, inside functions too: each module imported
    and the packages above it (their __init__ runs first), but not the root package (the face,
    imported before any of its modules) nor the importer's own packages (already importing)."""
    names = {name for name, _ in modules}
    graph = {}
    for name, path in modules:
        own = {name.rsplit(".", k)[0] for k in range(1, name.count(".") + 1)}
        targets = set()
        for module, _, _ in imports(path):
            parts = module.split(".")
            for k in range(2, len(parts) + 1):
                prefix = ".".join(parts[:k])
                if prefix in names and prefix not in own and prefix != name:
                    targets.add(prefix)
        graph[name] = targets
    return graph


def find_circle(graph: dict[str, set[str]]) -> list[str] | None:
    """One circle of ``graph`` (its modules, the first repeated at the end), or None if acyclic."""
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    path: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        path.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return [*path[path.index(nxt) :], nxt]
            if nxt not in state and (circle := visit(nxt)):
                return circle
        path.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state and (circle := visit(node)):
            return circle
    return None


def test_no_import_circle_among_the_package_s_modules():
    graph = import_graph(MODULES)
    circle = find_circle(graph)
    assert circle is None, "import circle: " + " -> ".join(circle or [])


def test_the_circle_check_finds_a_circle(tmp_path):
    """The check itself can fail: a lazy import that closes a circle through a package is found."""
    (tmp_path / "a.py").write_text("def f():\n    from stewart_env.dynamics import model\n")
    (tmp_path / "b.py").write_text("from stewart_env.params import bodies\n")
    (tmp_path / "c.py").write_text("import stewart_env.rotations\n")
    modules = [
        ("stewart_env.rotations", tmp_path / "a.py"),
        ("stewart_env.dynamics.model", tmp_path / "b.py"),
        ("stewart_env.params.bodies", tmp_path / "c.py"),
    ]
    assert find_circle(import_graph(modules)) == [
        "stewart_env.dynamics.model",
        "stewart_env.params.bodies",
        "stewart_env.rotations",
        "stewart_env.dynamics.model",
    ]
    assert find_circle({"x": {"y"}, "y": set()}) is None


def test_the_rule_catches_an_upward_import(tmp_path):
    """The check itself can fail: a physics module importing the environment is reported."""
    bad = tmp_path / "bad.py"
    bad.write_text("def f():\n    from stewart_env.envs import StewartPlatformEnv\n")
    assert [(m, layer_of(m)) for m, _, _ in imports(bad)] == [("stewart_env.envs", "envs")]
    bad.write_text("from stewart_env import mujoco, Reference\nfrom stewart_env.dynamics import rk4\n")
    assert [m for m, _, _ in imports(bad)] == ["stewart_env.mujoco", "stewart_env", "stewart_env.dynamics.rk4"]
    with pytest.raises(AssertionError):
        test_imports_run_one_way("stewart_env.kinematics", bad)
    # within the physics layer, a parameter module importing a kernel is reported
    bad.write_text("def f():\n    from stewart_env.dynamics import kernels as K\n")
    assert imports_above_the_parameters(bad) == ["line 2: stewart_env.dynamics.kernels"]
    bad.write_text("import numpy as np\nfrom mujoco import rollout\nimport mujoco.viewer\n")
    assert library_imports(bad) == [("numpy", 1), ("mujoco", 2), ("mujoco.viewer", 3)]


# -- the command line ------------------------------------------------------------------------------

CLI = "stewart_env.cli"
VERB_MODULES = (
    "demo",
    "evaluate",
    "reproduce",
    "train",
    "time_to_agent",
    "mismatch",
    "actuation",
    "cueing_results",
    "identify",
    "bench",
    "export_mjcf",
    "excitation",
    "record",
)


def test_only_the_command_line_imports_argparse():
    """The modules that do the work take values, not parsed arguments: argparse, its types and
    its parsers live in stewart_env/cli/."""
    found = [
        f"{name} line {line}"
        for name, path in MODULES
        for module, line in library_imports(path)
        if module == "argparse" and not (name == CLI or name.startswith(CLI + ".")) and name not in OWN_PARSERS
    ]
    assert found == []


def test_every_verb_is_a_module_of_the_command_line_with_its_two_functions():
    import importlib

    from stewart_env.cli import VERBS

    assert [module.__name__ for module in VERBS.values()] == [f"{CLI}.{name}" for name in VERB_MODULES]
    for module in VERBS.values():
        assert layer_of(module.__name__) == "cli"
        assert callable(module.add_parser) and callable(module.run)
    for name in (
        "agents.training.hyperparameters",
        "agents.training.rundir",
        "agents.training.trainer",
        "agents.training.agent",
        "agents.training.signals",
        "agents.training.env_kwargs",
    ):
        assert layer_of(importlib.import_module(f"stewart_env.{name}").__name__) == "agents"
    assert layer_of("stewart_env.extras") == "physics"
    assert layer_of("stewart_env._core") == "core"


def test_the_argparse_rule_catches_an_import(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text("def f():\n    import argparse\n")
    assert library_imports(bad) == [("argparse", 2)]
