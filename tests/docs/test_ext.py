"""The site's own Sphinx extension (docs/_ext/stewart_docs.py) on its own, without a build: the
env card split between a page's markers, and the table of the extras read from pyproject.toml."""

from __future__ import annotations

import sys

import pytest

from doc_blocks import ROOT

pytest.importorskip("sphinx", reason="the docs extra builds the site: pip install -e '.[docs]'")
sys.path.insert(0, str(ROOT / "docs" / "_ext"))
import stewart_docs  # noqa: E402
from sphinx.errors import ExtensionError  # noqa: E402


def test_the_card_is_split_between_the_markers_with_nothing_lost():
    card = stewart_docs.env_card()
    headings = [h for h, _ in stewart_docs.card_sections(card)]
    assert headings[:3] == ["Description", "Action Space", "Observation Space"]
    page = (
        "# Page\n\n<!-- generated: env card: Description -->\n\nour text\n\n"
        "<!-- generated: env card: Rewards, Action Space -->\n\n<!-- generated: env card -->\n"
    )
    out = stewart_docs.env_card_on_page(page)
    found = [line[3:] for line in out.splitlines() if line.startswith("## ")]
    rest = [h for h in headings if h not in ("Description", "Rewards", "Action Space")]
    assert found == ["Description", "Rewards", "Action Space", *rest]
    assert out.index("our text") < out.index("## Rewards")
    assert stewart_docs.env_card_on_page("<!-- generated: env card -->\n").strip() == card.strip()


def test_a_marker_of_a_section_the_card_lacks_is_one_clear_error():
    with pytest.raises(
        ExtensionError,
        match=r"environment: the env card has no section 'Rewardz' \(its sections: "
        r"Description, ",
    ):
        stewart_docs.env_card_on_page("<!-- generated: env card: Description, Rewardz -->\n", "environment")


def test_the_extras_are_pyproject_s_each_with_its_purpose():
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10
        tomllib = pytest.importorskip("tomli")
    declared = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    extras = stewart_docs.extras()
    assert [(extra, requirements) for extra, _, requirements in extras] == list(declared.items())
    purposes = {extra: purpose for extra, purpose, _ in extras}
    assert purposes["mujoco"].startswith("The MuJoCo twin")
    assert all(purpose.endswith(".") and not purpose.startswith("#") for purpose in purposes.values())


def test_an_extra_without_a_comment_is_one_clear_error(tmp_path, monkeypatch):
    pyproject = tmp_path / "pyproject.toml"
    pyproject.write_text(
        '[project]\nname = "x"\n\n[project.optional-dependencies]\n# Plotting.\nplots = ["matplotlib"]\n'
        'docs = ["sphinx"]\n'
    )
    monkeypatch.setattr(stewart_docs, "PYPROJECT", pyproject)
    with pytest.raises(ExtensionError, match=r"^pyproject.toml: the extra 'docs' has no comment above it"):
        stewart_docs.extras()
    pyproject.write_text(pyproject.read_text().replace("docs =", "# The site.\ndocs ="))
    assert stewart_docs.extras() == [("plots", "Plotting.", ["matplotlib"]), ("docs", "The site.", ["sphinx"])]


def test_the_site_without_its_mathjax_package_is_one_clear_error(monkeypatch):
    monkeypatch.setitem(sys.modules, "sphinx-mathjax-offline", None)  # as if not installed
    with pytest.raises(ExtensionError, match=r"sphinx-mathjax-offline, which is not installed: pip install -e "):
        stewart_docs._ship_mathjax(app=None)
