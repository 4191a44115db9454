"""The compiled extension under AddressSanitizer: built with STEWART_ENV_SANITIZE=address into a
temporary folder, it runs the tests of the physics and of the environment's compiled step with
AddressSanitizer's runtime preloaded into Python, and no read or write outside an array or into
freed memory may happen (a workspace bound to a parameter array the binding had to convert once
read that copy after it was freed).

Needs gcc (g++) with its libasan, CMake and nanobind, as a source install of the package does;
skipped, saying what is missing, without them."""

from __future__ import annotations

import importlib.util
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow  # a build of the extension (about 20 s of CPU time) and the tests under the sanitizer

ROOT = Path(__file__).resolve().parents[2]
SOURCES = ROOT / "stewart_env" / "_core" / "cpp"
#: The test files run under the sanitizer: the bindings' own and the environment's compiled step.
UNDER_SANITIZER = [
    "tests/dynamics",
    "tests/actuators",
    "tests/envs/test_compiled_step.py",
    "tests/envs/test_step_contract.py",
    "tests/envs/test_reset_speed_path.py",
]
#: Left out: this file, the choice of the instruction-set target (the run imports the baseline's),
#: and the CasADi model, whose IPOPT plugin CasADi loads with RTLD_DEEPBIND, which the sanitizer's
#: runtime refuses (it calls the derivatives' bindings, which test_derivatives.py runs here).
LEFT_OUT = [
    "tests/dynamics/test_sanitizer.py",
    "tests/dynamics/test_cpu_targets.py",
    "tests/dynamics/test_symbolic.py",
]
#: Seconds a build or the run of the tests may take before it counts as hung.
TIMEOUT = 900


def gcc_library(gcc: str, name: str) -> str | None:
    """The path of gcc's runtime library ``name`` (e.g. libasan.so), or None when gcc has none."""
    found = subprocess.run([gcc, f"-print-file-name={name}"], capture_output=True, text=True).stdout.strip()
    return found if os.path.isabs(found) and os.path.exists(found) else None


@pytest.fixture(scope="module")
def sanitized(tmp_path_factory):
    """(the AddressSanitizer build of the extension, the libraries to preload), or a skip naming
    what this machine lacks."""
    gcc, gxx, cmake = shutil.which("gcc"), shutil.which("g++"), shutil.which("cmake")
    if not (gcc and gxx):
        pytest.skip("needs gcc and g++ to build the extension with AddressSanitizer")
    if cmake is None:
        pytest.skip("needs cmake to build the extension")
    if importlib.util.find_spec("nanobind") is None:
        pytest.skip("needs nanobind to build the extension")
    libasan = gcc_library(gcc, "libasan.so")
    if libasan is None:
        pytest.skip("needs gcc's AddressSanitizer runtime (libasan.so; Debian: libasan8 with gcc 12)")
    # libstdc++ loaded with the sanitizer, before any extension: its C++ exceptions then go
    # through the sanitizer's interceptor, which otherwise finds no __cxa_throw to call
    libstdcxx = gcc_library(gcc, "libstdc++.so")
    build = tmp_path_factory.mktemp("asan-build")
    configure = [
        cmake,
        "-S",
        str(SOURCES),
        "-B",
        str(build),
        "-DSTEWART_ENV_SANITIZE=address",
        "-DSTEWART_ENV_PORTABLE=ON",
        f"-DCMAKE_CXX_COMPILER={gxx}",
        f"-DPython_EXECUTABLE={sys.executable}",
    ]
    for step in (configure, [cmake, "--build", str(build), "-j", str(os.cpu_count() or 1)]):
        done = subprocess.run(step, capture_output=True, text=True, timeout=TIMEOUT)
        assert done.returncode == 0, f"{' '.join(step)} failed:\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    (module,) = build.glob("_core_baseline*.so")  # STEWART_ENV_PORTABLE=ON: the baseline target alone
    return module, [p for p in (libasan, libstdcxx) if p]


PLUGIN = '''
"""Loads the AddressSanitizer build of the kernels as stewart_env._core._core_baseline, before
the package is imported (a pytest plugin given with -p is imported before any conftest);
STEWART_ENV_CPU=baseline then has stewart_env._core take it."""
import importlib.util
import sys

PATH = {path!r}
NAME = "stewart_env._core._core_baseline"
spec = importlib.util.spec_from_file_location(NAME, PATH)
module = importlib.util.module_from_spec(spec)
spec.loader.exec_module(module)
sys.modules[NAME] = module


def pytest_configure(config):
    from stewart_env import _core

    if _core._kernels.__file__ != PATH:
        raise RuntimeError("the sanitized kernels are not the ones stewart_env imported")
'''


def test_the_bindings_read_and_write_only_live_memory_under_address_sanitizer(sanitized, tmp_path):
    module, preload = sanitized
    (tmp_path / "asan_core.py").write_text(textwrap.dedent(PLUGIN.format(path=str(module))))
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(tmp_path), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep),
        "LD_PRELOAD": " ".join(preload),
        # leaks: Python's own allocations at exit are none of the extension's; allocator_may_return_null:
        # the tests that ask for a workspace too large to allocate expect a MemoryError, not an abort
        "ASAN_OPTIONS": f"detect_leaks=0:allocator_may_return_null=1:log_path={tmp_path / 'asan'}",
        "STEWART_ENV_CPU": "baseline",
        "MPLBACKEND": "Agg",
        "OPENBLAS_NUM_THREADS": "1",
    }
    command = [
        sys.executable,
        "-m",
        "pytest",
        "-q",
        "-p",
        "no:cacheprovider",
        "-p",
        "asan_core",
        "-m",
        "not slow",
        *(f"--ignore={path}" for path in LEFT_OUT),
        *UNDER_SANITIZER,
    ]
    done = subprocess.run(command, cwd=ROOT, env=env, capture_output=True, text=True, timeout=TIMEOUT)
    reports = "\n".join(path.read_text() for path in sorted(tmp_path.glob("asan.*")))
    assert "ERROR: AddressSanitizer" not in reports, reports[:6000]
    assert done.returncode == 0, f"{done.stdout[-4000:]}\n{done.stderr[-2000:]}"
    assert " passed" in done.stdout and " failed" not in done.stdout
