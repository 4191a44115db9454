"""The project's checks, one nox session each, every one in a fresh virtual environment.

``nox -l`` lists them, ``nox -s core`` runs one; arguments after ``--`` go to the session's
command (pytest's, sphinx's or ``stewart-env bench``'s).
"""

from __future__ import annotations

import nox

# `nox` alone runs the quick ones
nox.options.sessions = ["lint", "core"]

#: The one version of ruff the rules of pyproject.toml's [tool.ruff] are written for (the test extra's).
RUFF = "ruff==0.17.6"
#: torch as the README's test command installs it, from PyTorch's index of the CPU build.
TORCH = ("torch==2.13.0", "--index-url", "https://download.pytorch.org/whl/cpu")


@nox.session
def core(session: nox.Session) -> None:
    """The package alone (no extra), and the tests that are not slow; the others skip themselves."""
    session.install("-e", ".")
    # the runner and the property tests' library, not a feature of the package
    session.install("pytest", "hypothesis")
    session.run(
        "python",
        "-m",
        "pytest",
        "-q",
        "-m",
        "not slow and not integration",
        *session.posargs,
        env={"MPLBACKEND": "Agg"},
    )


@nox.session
def tests(session: nox.Session) -> None:
    """The whole suite with every extra it drives, as the README's test command installs them."""
    session.install(*TORCH)
    session.install("-e", ".[rl,test,integration,mujoco,distributed,docs,logs,casadi,mpc,jsbsim,video]")
    session.run("python", "-m", "pytest", "-q", *session.posargs, env={"MPLBACKEND": "Agg"})


@nox.session
def docs(session: nox.Session) -> None:
    """The documentation site, built into docs/_build/html with warnings as errors."""
    session.install("-e", ".[docs]")
    session.run(
        "python", "-m", "sphinx", "-W", "-n", "--keep-going", "-b", "html", "docs", "docs/_build/html", *session.posargs
    )


@nox.session
def bench(session: nox.Session) -> None:
    """The benchmark as docs/results/benchmark.md runs it, beside MuJoCo; it redraws the page's figure."""
    session.install("-e", ".[mujoco]")
    arguments = session.posargs or ["--env", "--mujoco", "--plot", "docs/figures/benchmark_scaling.png"]
    session.run("stewart-env", "bench", *arguments)


@nox.session
def lint(session: nox.Session) -> None:
    """The checks of pyproject.toml's [tool.ruff] rules and the formatting of ``ruff format``."""
    session.install(RUFF)
    session.run("ruff", "check", ".", *session.posargs)
    session.run("ruff", "format", "--check", ".")
