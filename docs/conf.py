"""Sphinx configuration of the stewart-env site (Furo theme, MyST Markdown pages).

Build: ``python -m sphinx -W -n --keep-going -b html docs docs/_build/html`` from the
repository's root (the ``docs`` extra installs what it needs).
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE / "_ext"))

import stewart_env  # noqa: E402

project = "stewart-env"
author = "the stewart-env contributors"
copyright = "the stewart-env contributors"
release = stewart_env.__version__
version = release

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    # MathJax itself comes with the site, not from a CDN (stewart_docs sets it up)
    "sphinx.ext.mathjax",
    "stewart_docs",
]

source_suffix = {".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "figures/**/*.md", "figures/**/*.csv"]

# MyST: $...$ maths (docs/physics.md), ::: fences, and GitHub's heading anchors, so that a
# page's [text](#heading) links work on the site as they do on GitHub.
myst_enable_extensions = ["dollarmath", "colon_fence"]
myst_heading_anchors = 4

# Google-style docstrings (Args, Returns, Raises).
napoleon_google_docstring = True
napoleon_numpy_docstring = False
# Attributes: sections as fields of their class, so that a record's fields (NamedTuple, dataclass)
# documented there and by autodoc are not described twice.
napoleon_use_ivar = True
autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_default_options = {"members": True, "show-inheritance": False}

nitpicky = True
# The site is built offline (no intersphinx inventories): names of Python's standard library and
# of the libraries stewart-env builds on are not cross-referenced.
nitpick_ignore_regex = [
    (
        r"py:.*",
        r"(numpy|np|collections|enum|os|pathlib|argparse|typing|gymnasium|gym|numba|mujoco|matplotlib"
        r"|stable_baselines3|torch|ray)(\..*)?",
    ),
    (r"py:class", r"(ObsType|ActType|AutoresetMode|Path|optional .*)"),
]
# Names that docstrings of the public API mention but that are not public themselves (private
# bases, helpers, the compiled kernels' modules): shown as code, not linked.
nitpick_ignore_regex += [
    (r"py:.*", r"stewart_env\..*\._\w+|_\w+"),
    (
        r"py:.*",
        r"stewart_env\.(dynamics\.(rk4|kernels|model\.batch_args|model\.ROTATION_TOLERANCE)"
        r"|validation|envs\.\w+\.BatchAttributes|agents\.controllers\.pd\.EnvPolicy|agents\.evaluation\.evaluation\.Episode"
        r"|agents\.training\.hyperparameters\.Hyperparameters"
        r"|rotations\.rpy_rate_matrix)",
    ),
    (
        r"py:.*",
        r"EnvPolicy|TrainingInterrupted|rollout_steps|simulate_case_study|peak_differences|empty_errors"
        r"|Task\.initialize_episode|Reference|PlatformState|PlatformParams|pose_margins",
    ),
    # the site documents packages, not each of their modules
    (r"py:mod", r"stewart_env(\..*)?"),
    # a description after a colon in a Returns line, read by napoleon as a type
    (r"py:class", r"6|h|a; alpha|The reasons that end an episode with a success|A short label for tables"),
]
# gymnasium's docstrings of methods stewart-env does not document itself stay gymnasium's
autodoc_inherit_docstrings = False

html_theme = "furo"
html_title = f"stewart-env {release}"
html_static_path = ["_static"]
html_css_files = ["stewart-env.css"]
