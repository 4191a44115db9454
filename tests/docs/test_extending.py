"""The extending guide (docs/guides/extending.md) works as written: its package files, taken from
the page's ``# file:`` blocks, make a package outside the repository whose own environment id
Gymnasium makes and steps, in a fresh interpreter as a user would run it."""

import re
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
GUIDE = ROOT / "docs" / "guides" / "extending.md"
ENV_ID = "my_stewart/LiftPlatform-v0"
# a fresh interpreter imports stewart_env and loads the cached kernels in a few seconds
RUN_TIMEOUT_S = 300


def guide_blocks() -> list[tuple[str, str]]:
    """(info string, text) of the guide's fenced blocks, in order."""
    return re.findall(r"^```(\w*)\n(.*?)^```", GUIDE.read_text(), flags=re.S | re.M)


@pytest.fixture(scope="module")
def package(tmp_path_factory) -> Path:
    """The directory holding the guide's package, written from its ``# file:`` blocks."""
    where = tmp_path_factory.mktemp("user")
    files = [text for _, text in guide_blocks() if text.startswith("# file: ")]
    assert len(files) == 3  # the task, the platform config, the package's registration
    for text in files:
        path = where / text.splitlines()[0].removeprefix("# file: ").strip()
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return where


def run(code: str, cwd: Path) -> str:
    done = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)], cwd=cwd, capture_output=True, text=True, timeout=RUN_TIMEOUT_S
    )
    assert done.returncode == 0, done.stderr[-3000:]
    return done.stdout


def test_the_guide_usage_runs_and_prints_what_it_says(package):
    (usage,) = [text for tag, text in guide_blocks() if tag == "python" and not text.startswith("# file: ")]
    printed = run(usage, package).splitlines()
    stated = re.findall(r"\)  # (.+)$", usage, flags=re.M)
    assert len(printed) == len(stated) == 2
    assert printed[0] == stated[0]  # the task's name and the heavy platform's mass: "lift 60.0"
    assert np.allclose(np.array(printed[1].strip("[]").split(), float), np.array(stated[1].strip("[]").split(), float))


def test_the_users_id_steps_with_the_users_task_and_platform(package):
    out = run(
        """
        import gymnasium as gym
        import numpy as np
        import my_stewart
        from my_stewart.tasks import LiftTask
        from stewart_env.agents import PDPolicy, evaluate

        assert "my_stewart/LiftPlatform-v0" in gym.registry
        env = gym.make("my_stewart/LiftPlatform-v0")
        obs, info = env.reset(seed=0)
        u = env.unwrapped
        assert isinstance(u.task, LiftTask) and u.platform.platform.mass == 60.0
        assert np.allclose(u.target.position - u.platform.home_position, [0, 0, 0.02])  # the default lift
        for _ in range(5):
            obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
            assert np.isfinite(obs).all() and -10.2 <= reward <= 1.0  # the reward's bounds (env card)
        # the vector environment and the evaluation harness take the same task
        envs = gym.make_vec("StewartPlatform-v1", num_envs=4, vectorization_mode="vector_entry_point", task=LiftTask,
                            platform=u.platform)
        envs.reset(seed=0)
        envs.step(envs.action_space.sample())
        result = evaluate(lambda e: PDPolicy(e, gravity_compensation=True), {"task": LiftTask, "platform": u.platform},
                          episodes=1, seed=0)
        print(result.summary()["success"])
    """,
        package,
    )
    assert float(out.split()[-1]) == 1.0  # PD with the exact holding forces reaches a 2 cm lift


def test_the_module_qualified_id_imports_the_package(package):
    """Worker processes need the id that names its module; Gymnasium then imports the package."""
    out = run(
        """
        import gymnasium as gym
        env = gym.make("my_stewart:my_stewart/LiftPlatform-v0")
        env.reset(seed=0)
        print(env.unwrapped.task.name)
    """,
        package,
    )
    assert out.split() == ["lift"]
