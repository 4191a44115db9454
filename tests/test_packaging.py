"""The tests import the checkout they belong to, and every module finds the shipped configs alike,
installed or from the source tree."""

import importlib.metadata
import importlib.resources
import re
import subprocess
import sys

import pytest
import yaml

import stewart_env
import stewart_env.params as params_module
from stewart_env.agents import training
from stewart_env.params import config_dir

from conftest import CHECKOUT_MODULES, REPOSITORY, foreign_modules


def test_the_tests_import_this_checkout():
    assert foreign_modules() == []


def test_another_checkout_is_detected(tmp_path):
    # seen from a repository that is not the one imported, every checkout module is foreign
    foreign = foreign_modules(tmp_path)
    assert len(foreign) == len(CHECKOUT_MODULES) == 3
    assert foreign[1] == f"stewart_env.agents from {REPOSITORY / 'agents' / '__init__.py'}"


def test_a_foreign_module_stops_the_run_naming_it(monkeypatch):
    import conftest

    monkeypatch.setattr(conftest, "foreign_modules", lambda: ["stewart_env.agents from /elsewhere/agents/__init__.py"])
    with pytest.raises(
        pytest.UsageError, match=r"would import stewart_env\.agents from /elsewhere/agents/__init__\.py"
    ):
        conftest.pytest_configure(None)


def test_the_installed_version_is_stewart_env_version():
    assert importlib.metadata.version("stewart-env") == stewart_env.__version__


def test_the_version_is_written_once():
    # pyproject.toml reads it from stewart_env/__init__.py (scikit-build-core's regex provider);
    # the citation metadata carries none, the version cited is the one used
    pyproject = (REPOSITORY / "pyproject.toml").read_text(encoding="utf-8")
    assert re.search(r'^dynamic = \["version"\]$', pyproject, flags=re.M)
    assert not re.search(r"^version\s*=", pyproject, flags=re.M)
    assert 'input = "stewart_env/__init__.py"' in pyproject
    assert "version" not in yaml.safe_load((REPOSITORY / "CITATION.cff").read_text(encoding="utf-8"))
    assert stewart_env.__version__ not in (REPOSITORY / "docs" / "citing.md").read_text(encoding="utf-8")


@pytest.mark.parametrize(("kind", "example"), [("platforms", "dasgupta1998.yaml"), ("agents", "ppo.yml")])
def test_config_dir_is_the_checkouts_configs(kind, example):
    assert config_dir(kind) == REPOSITORY / "configs" / kind
    assert (config_dir(kind) / example).is_file()


def test_training_reads_the_agent_configs_through_config_dir():
    assert training.CONFIG_DIR == config_dir("agents")
    assert training.read_hyperparameters("ppo", None)  # the shipped ppo.yml


@pytest.mark.parametrize("installed", ["missing", "without configs"])
def test_config_dir_falls_back_to_the_source_tree(installed, monkeypatch, tmp_path):
    def files(name):
        if installed == "missing":
            raise ModuleNotFoundError(f"No module named {name!r}")
        return tmp_path  # an installed stewart_env.configs that holds no platforms/ folder

    monkeypatch.setattr(importlib.resources, "files", files)
    assert config_dir("platforms") == REPOSITORY / "configs" / "platforms"
    assert "dasgupta1998" in params_module.available_platforms()


@pytest.mark.slow
def test_the_wheel_holds_the_compiled_extensions_and_the_configs(tmp_path):
    """``pip wheel .`` compiles the physics into the wheel, once per instruction-set target, and
    ships the configs and agents inside the package, and not the C++ sources (about two minutes:
    it compiles the kernels three times)."""
    import platform
    import re
    import shutil
    import subprocess
    import sys
    import zipfile

    pytest.importorskip("scikit_build_core")  # the build backend, from the extra "test"
    pytest.importorskip("nanobind")
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "wheel",
            "--no-deps",
            "--no-build-isolation",
            "-w",
            str(tmp_path),
            str(REPOSITORY),
        ],
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert result.returncode == 0, result.stderr[-3000:]
    (wheel,) = tmp_path.glob("stewart_env-*.whl")
    names = zipfile.ZipFile(wheel).namelist()
    extensions = {
        n.split("/")[-1].split(".")[0]: n
        for n in names
        if n.startswith("stewart_env/_core/_") and n.endswith((".so", ".pyd"))
    }
    targets = ["_core_baseline"]
    if sys.platform.startswith("linux") and platform.machine() == "x86_64":
        targets += ["_core_x86_64_v3", "_core_x86_64_v4"]
    assert sorted(extensions) == sorted([*targets, "_cpu_features"])
    for shipped in (
        "stewart_env/configs/platforms/dasgupta1998.yaml",
        "stewart_env/configs/agents/ppo.yml",
        "stewart_env/agents/controllers/pd.py",
        "stewart_env/dynamics/kernels.py",
        "stewart_env/_core/__init__.py",
    ):
        assert shipped in names
    assert not [n for n in names if "/cpp/" in n or n.endswith((".hpp", ".cpp"))]
    # the wheel's metadata carries the version of stewart_env/__init__.py
    metadata = zipfile.ZipFile(wheel).read(f"stewart_env-{stewart_env.__version__}.dist-info/METADATA").decode()
    assert f"\nVersion: {stewart_env.__version__}\n" in metadata
    if shutil.which("objdump") and platform.machine() == "x86_64":
        # the baseline runs on any x86-64 processor: no AVX register; and no target fuses a
        # multiply and an add, which would change the numbers from one target to another
        zipfile.ZipFile(wheel).extractall(tmp_path / "wheel")
        for module, path in extensions.items():
            code = subprocess.run(
                ["objdump", "-d", str(tmp_path / "wheel" / path)], capture_output=True, text=True, check=True
            ).stdout
            assert not re.search(r"\tvfn?m(add|sub)", code), module
            if module in ("_core_baseline", "_cpu_features"):
                assert "%ymm" not in code and "%zmm" not in code, module


def test_making_the_environment_imports_no_slow_library():
    # scipy.signal's import alone takes about a second, scipy.stats' and torch's more: a user's
    # `gym.make` pays for none of them (the cueing motions and perception import them when used)
    code = (
        "import sys, gymnasium, stewart_env\n"
        "gymnasium.make('StewartPlatform-v1').reset(seed=0)\n"
        "print(sorted(m for m in ('scipy.signal', 'scipy.stats', 'torch', 'casadi', 'osqp', 'jsbsim') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True)
    assert out.stdout.strip() == "[]"
