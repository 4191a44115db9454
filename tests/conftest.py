import importlib.util
from pathlib import Path

import numpy as np
import pytest

import stewart_env as se

#: The checkout these tests belong to.
REPOSITORY = Path(__file__).resolve().parent.parent
#: The modules that must come from it, and where in it: configs/ and agents/ sit at the top of the
#: repository and an editable install maps them into the package, so with checkout A installed
#: editable, the tests of checkout B would otherwise silently import A's agents and configs.
CHECKOUT_MODULES = {"stewart_env": "stewart_env", "stewart_env.agents": "agents", "stewart_env.configs": "configs"}


def foreign_modules(repository: Path = REPOSITORY) -> list[str]:
    """The modules of CHECKOUT_MODULES that Python would import from outside ``repository``'s folders,
    each as "name from path" (path None when the module is not found)."""
    foreign = []
    for name, folder in CHECKOUT_MODULES.items():
        spec = importlib.util.find_spec(name)
        origin = None if spec is None or spec.origin is None else Path(spec.origin).resolve()
        if origin is None or not origin.is_relative_to(repository / folder):
            foreign.append(f"{name} from {origin}")
    return foreign


#: The optional modules behind each extra, as ``@pytest.mark.extra("rl")`` names them.
EXTRA_MODULES = {
    "rl": ("stable_baselines3", "moviepy"),
    "mujoco": ("mujoco",),
    "distributed": ("ray",),
    "integration": ("torchrl", "tianshou", "skrl", "rl_zoo3"),
    "docs": ("sphinx", "furo", "myst_parser"),
    "laws": ("numba",),
    "jsbsim": ("jsbsim",),
    "casadi": ("casadi",),
    "mpc": ("osqp",),
}


def exit_code(argv) -> int:
    """The exit code of ``stewart-env argv``, whether argparse (SystemExit) or the command (its
    return value) refused it."""
    from stewart_env.cli import main

    try:
        return main(argv)
    except SystemExit as stop:
        return stop.code


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item):
    """Skip a test marked ``extra(name, ...)`` when an extra it needs is not installed, before its
    fixtures are set up (a core install runs the rest of the suite and passes)."""
    for mark in item.iter_markers("extra"):
        for extra in mark.args:
            for module in EXTRA_MODULES[extra]:
                if importlib.util.find_spec(module) is None:
                    pytest.skip(f"needs the {extra} extra ({module} is not installed)")


def pytest_configure(config):
    """Refuse to run, before collecting any test, when the tests would not test this checkout."""
    if foreign := foreign_modules():
        raise pytest.UsageError(
            f"these tests belong to the checkout {REPOSITORY}, but Python would import "
            + "; ".join(foreign)
            + f". Install this checkout (pip install -e {REPOSITORY}) or run its tests in an environment "
            "where it is the one installed."
        )


@pytest.fixture(scope="session")
def dasgupta():
    return se.load_platform("dasgupta1998")


@pytest.fixture(scope="session")
def simulator():
    return se.load_platform("motion_simulator")


@pytest.fixture
def rng():
    return np.random.default_rng(20180523)


@pytest.fixture
def headless(monkeypatch):
    """No display, as on CI and servers: human rendering must warn once and draw nothing."""
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)


@pytest.fixture(scope="module")
def model(dasgupta):
    """The improved model of the example platform."""
    return se.make_dynamics("improved", dasgupta)


@pytest.fixture
def home(model):
    """The home pose (position, rotation) and a zero rate."""
    ws = model.workspace(1)
    return ws.position[0].copy(), ws.rotation[0].copy(), np.zeros(3)


@pytest.fixture
def make():
    """``make(**kwargs)``: ``gymnasium.make("StewartPlatform-v1", **kwargs)``, reset with seed 0."""
    gym = pytest.importorskip("gymnasium")

    def make(**kwargs):
        env = gym.make("StewartPlatform-v1", **kwargs)
        env.reset(seed=0)
        return env

    return make
