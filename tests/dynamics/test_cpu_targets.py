"""The kernels' instruction-set targets (stewart_env/_core/__init__.py): every target the processor
runs gives the same numbers bit for bit, the best one is imported by default, ``STEWART_ENV_CPU``
chooses another, and a value it cannot honour is a warning naming the variable."""

from __future__ import annotations

import os
import platform
import subprocess
import sys
from pathlib import Path

import pytest

from stewart_env import _core
from stewart_env._core import _cpu_features
from stewart_env.errors import UsageError

# Run in a fresh interpreter with STEWART_ENV_CPU set: prints the target imported and one hash of
# the outputs of the kernels, the integrator, the compiled control law and both environments.
HASH_OUTPUTS = """
import hashlib
import gymnasium as gym
import numpy as np
import stewart_env as se
from stewart_env import _core
from stewart_env.agents.controllers.pd import pd_control_law, pd_control_params

digest = hashlib.sha256()
def add(*arrays):
    for a in arrays:
        digest.update(np.ascontiguousarray(a).tobytes())

params = se.load_platform("dasgupta1998")
rng = np.random.default_rng(7)
n = 1000
t = params.home_position + rng.uniform(-0.05, 0.05, (n, 3))
R = se.rpy_to_matrix(params.home_rpy + rng.uniform(-0.15, 0.15, (n, 3)))
v, w = rng.normal(scale=0.5, size=(n, 3)), rng.normal(scale=1.0, size=(n, 3))
F = rng.normal(scale=300.0, size=(n, 6)) + 180.0
W = np.hstack([rng.normal(scale=50.0, size=(n, 3)), rng.normal(scale=5.0, size=(n, 3))])
acc = rng.normal(size=(n, 6))
for name in ("classical", "improved", "improved_centroidal", "improved+c1", "improved+c2+c3", "improved+c4"):
    model = se.make_dynamics(name, params)
    add(*model.forward(t, R, v, w, F, W), model.inverse(t, R, v, w, acc[:, :3], acc[:, 3:], W))
    state = se.rollout(model, t[:64], R[:64], v[:64], w[:64], F[:64], dt=1e-3, steps=100)
    add(*state)
model = se.make_dynamics("improved", params)
home = se.Reference(params.home_position, se.rpy_to_matrix(params.home_rpy), np.zeros(3), np.zeros(3))
law_params = pd_control_params(params, home, gravity_compensation=True)
add(*se.rollout(model, t[:16], R[:16], v[:16], w[:16], dt=1e-3, steps=200, control_law=pd_control_law,
                control_params=law_params))
# the exact derivatives: a block of eight rows in vector lanes and three left over
add(*model.acceleration_jacobians(t[:11], R[:11], v[:11], w[:11], F[:11], W[:11]))
jac = model.step_jacobians(t[:11], R[:11], v[:11], w[:11], F[:11], 0.01, 10, W[:11])
add(jac.A, jac.B, *jac.state)

env = gym.make("StewartPlatform-v1", task="tracking")
obs, _ = env.reset(seed=0)
add(obs)
actions = np.random.default_rng(1).uniform(-1, 1, (60, 6))
for action in actions:
    obs, reward, terminated, truncated, _ = env.step(action)
    add(obs, np.float64(reward), np.bool_(terminated))
    if terminated or truncated:
        obs, _ = env.reset()
envs = gym.make_vec("StewartPlatform-v1", num_envs=16, vectorization_mode="vector_entry_point", task="setpoint")
add(envs.reset(seed=3)[0])
for action in np.random.default_rng(2).uniform(-1.5, 1.5, (40, 16, 6)):
    obs, reward, terminated, truncated, _ = envs.step(action)
    add(obs, reward, terminated, truncated)
print(_core.TARGET, digest.hexdigest())
"""


def run_with_target(target: str, code: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "STEWART_ENV_CPU": target}
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300)


def test_every_target_the_processor_runs_gives_the_same_numbers():
    """A fresh interpreter per target, about 1.5 s each."""
    targets = [t for t in _core._built_targets() if t in _cpu_features.runnable()]
    if len(targets) < 2:
        pytest.skip(f"nothing to compare: the one target built and runnable is {targets[0]}")
    hashes = {}
    for target in targets:
        result = run_with_target(target, HASH_OUTPUTS)
        assert result.returncode == 0, result.stderr[-3000:]
        imported, digest = result.stdout.split()
        assert imported == target
        hashes[target] = digest
    assert len(set(hashes.values())) == 1, hashes


def test_the_default_is_the_most_demanding_target_built_and_runnable():
    usable = [t for t in _core._built_targets() if t in _cpu_features.runnable()]
    if os.environ.get("STEWART_ENV_CPU"):
        pytest.skip("STEWART_ENV_CPU chooses the target of this run")
    assert _core.TARGET == usable[-1]
    assert _core._choose("", ["baseline", "x86-64-v3", "x86-64-v4"], ["baseline", "x86-64-v3"]) == "x86-64-v3"
    assert _core._choose("", ["baseline"], ["baseline", "x86-64-v3", "x86-64-v4"]) == "baseline"


def test_every_build_holds_the_baseline():
    built = _core._built_targets()
    assert built[0] == "baseline"
    assert _core.TARGET in built


@pytest.mark.parametrize(
    ("requested", "built", "runnable", "message"),
    [
        (
            "x86-64-v9",
            ["baseline", "x86-64-v3"],
            ["baseline", "x86-64-v3"],
            "STEWART_ENV_CPU='x86-64-v9': not a target; choose one of baseline, x86-64-v3, x86-64-v4, or unset it",
        ),
        (
            "x86-64-v4",
            ["baseline", "x86-64-v3", "x86-64-v4"],
            ["baseline", "x86-64-v3"],
            "STEWART_ENV_CPU='x86-64-v4': this processor cannot run it (it runs: baseline, x86-64-v3)",
        ),
        (
            "x86-64-v3",
            ["baseline"],
            ["baseline", "x86-64-v3"],
            "STEWART_ENV_CPU='x86-64-v3': not built in this installation (built: baseline)",
        ),
    ],
)
def test_a_target_that_cannot_be_had_is_an_error_naming_the_variable(requested, built, runnable, message):
    with pytest.raises(UsageError) as error:
        _core._choose(requested, built, runnable)
    assert str(error.value).startswith(message)


def test_an_unknown_target_is_a_warning_naming_the_variable_and_the_fastest_target_runs():
    result = run_with_target("avx512", "import stewart_env; from stewart_env import _core; print(_core.TARGET)")
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == _core.TARGET  # the default choice, as with the variable unset
    assert (
        "RuntimeWarning: STEWART_ENV_CPU='avx512': not a target; choose one of baseline, x86-64-v3, x86-64-v4, "
        f"or unset it for the fastest this processor runs; using {_core.TARGET}"
    ) in result.stderr


def test_an_unknown_target_leaves_the_command_line_working():
    result = run_with_target("avx512", "from stewart_env.cli import main; raise SystemExit(main(['--version']))")
    assert result.returncode == 0, result.stderr
    assert "Traceback" not in result.stderr


@pytest.mark.skipif(
    not (sys.platform.startswith("linux") and platform.machine() == "x86_64"),
    reason="reads the flags of Linux's /proc/cpuinfo on x86-64",
)
def test_the_runnable_targets_agree_with_the_kernels_view_of_the_processor():
    """The compiled CPUID check against the flags Linux reports (the kernel clears a flag whose
    registers it does not save)."""
    flags = set()
    for line in Path("/proc/cpuinfo").read_text().splitlines():
        if line.startswith("flags"):
            flags = set(line.split(":", 1)[1].split())
            break
    v3 = {
        "avx",
        "avx2",
        "bmi1",
        "bmi2",
        "f16c",
        "fma",
        "abm",
        "movbe",
        "xsave",
        "cx16",
        "lahf_lm",
        "popcnt",
        "pni",
        "sse4_1",
        "sse4_2",
        "ssse3",
    }
    v4 = {"avx512f", "avx512bw", "avx512cd", "avx512dq", "avx512vl"}
    expected = ["baseline"] + ["x86-64-v3"] * (v3 <= flags) + ["x86-64-v4"] * (v3 <= flags and v4 <= flags)
    assert _cpu_features.runnable() == expected


def test_the_benchmark_names_the_target_that_runs():
    result = run_with_target("baseline", "from stewart_env.benchmarks import machine; print(machine())")
    assert result.returncode == 0, result.stderr[-3000:]
    assert ", kernels for baseline, Python " in result.stdout
