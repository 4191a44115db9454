"""The documentation site (docs/) builds clean, every link and image of it resolves, a browser
shows its pages without errors, and its pages run as written.

- The build is Sphinx's with warnings as errors and every cross-reference resolved
  (``-W -n --keep-going``), so a docstring the API reference cannot render, a link to a missing
  page or a reference to a missing object fails it.
- Every internal link (``href``) and image (``src``) of the built HTML names a file of the build,
  and every ``#anchor`` an element of its page.
- Headless Chromium opens the home page and the environment page: no script error, every image
  loaded, and a screenshot written.
- Every code block of every page, the pages taken in the order of the contents, runs as the README's
  do (``tests/doc_blocks.py``: one working directory, ``# long:`` commands only parsed), and the
  tables that cheap, seeded commands print are the tables the pages show.
"""

from __future__ import annotations

import html
import os
import re
import shlex
import shutil
import subprocess
import sys
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit

import pytest

from doc_blocks import (
    ROOT,
    aligned_tables,
    block_and_table,
    block_and_text_table,
    compare_table,
    markdown_tables,
    run_documents,
    same_figure,
    snippet_figures,
    snippets_write_what_they_say,
    states_the_long_convention,
)

pytestmark = pytest.mark.slow

DOCS = ROOT / "docs"
# a clean build of the whole site, API reference and generated pages included, takes about a minute
BUILD_TIMEOUT_S = 600
# a browser that has not shown a local page in this time is hung
BROWSER_TIMEOUT_S = 120
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


def site_pages(document: str = "index", seen: list[str] | None = None) -> list[str]:
    """The site's pages in the order of its contents: a page, then the pages its tables of
    contents list, depth first (the names as Sphinx knows them, relative to docs/ without .md)."""
    seen = [] if seen is None else seen
    seen.append(document)
    text = (DOCS / f"{document}.md").read_text()
    for toctree in re.findall(r"^```\{toctree\}\n(.*?)^```", text, flags=re.S | re.M):
        for line in toctree.splitlines():
            entry = line.strip()
            if not entry or entry.startswith(":"):
                continue
            name = str(Path(document).parent / entry) if "/" in document else entry
            if name not in seen:
                site_pages(name, seen)
    return seen


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    """The built site: Sphinx's HTML output directory."""
    for module in ("sphinx", "furo", "myst_parser"):
        pytest.importorskip(module, reason="the docs extra builds the site: pip install -e '.[docs]'")
    out = tmp_path_factory.mktemp("site") / "html"
    done = subprocess.run(
        [sys.executable, "-m", "sphinx", "-W", "-n", "--keep-going", "-E", "-q", "-b", "html", str(DOCS), str(out)],
        capture_output=True,
        text=True,
        timeout=BUILD_TIMEOUT_S,
        env={**os.environ, "MPLBACKEND": "Agg"},
    )
    assert done.returncode == 0, f"the site does not build clean:\n{done.stderr[-6000:]}"
    return out


def test_every_page_is_in_the_contents(site):
    """No page is left out of the contents (Sphinx would warn), and the contents name only pages."""
    pages = site_pages()
    sources = {
        str(p.relative_to(DOCS).with_suffix(""))
        for p in DOCS.rglob("*.md")
        if not p.relative_to(DOCS).parts[0].startswith(("_", "figures"))
    }
    assert set(pages) == sources
    assert all((site / f"{page}.html").is_file() for page in pages)


class _Links(HTMLParser):
    def __init__(self):
        super().__init__()
        self.ids, self.links = set(), []

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if attrs.get("id"):
            self.ids.add(attrs["id"])
        if tag == "a" and attrs.get("name"):
            self.ids.add(attrs["name"])
        for key in ("href", "src"):
            if attrs.get(key) is not None and not (tag == "link" and attrs.get("rel") in ("canonical",)):
                self.links.append((tag, key, attrs[key]))


def test_every_internal_link_and_image_resolves(site):
    pages = {}
    for path in site.rglob("*.html"):
        parser = _Links()
        parser.feed(path.read_text(encoding="utf-8"))
        pages[path.resolve()] = parser
    broken, checked = [], 0
    for path, parser in pages.items():
        for tag, key, url in parser.links:
            parts = urlsplit(url)
            if parts.scheme or url.startswith("//"):
                continue  # another site: http(s), mailto, data
            target = (path.parent / unquote(parts.path)).resolve() if parts.path else path
            checked += 1
            if not target.is_file():
                broken.append(f"{path.relative_to(site)}: <{tag} {key}={url!r}>: no such file")
            elif parts.fragment and target.suffix == ".html" and unquote(parts.fragment) not in pages[target].ids:
                broken.append(f"{path.relative_to(site)}: <{tag} {key}={url!r}>: no such anchor")
    assert checked > 500  # the pages were parsed: the theme alone links each page to every other
    assert not broken, "\n".join(broken)


def test_the_figures_of_the_pages_are_in_the_site(site):
    """Every image a page shows is in the build, the environment page's generated frames included."""
    images = {p.name for p in (site / "_images").iterdir()}
    assert {"episode.png", "fig10_leg_forces.png", "forest.png"} <= images
    assert (site / "_images" / "episode.png").stat().st_size > 10_000  # drawn, not an empty canvas


# Inserted at the top of a page's <head>: after the page has loaded, every image must have loaded.
PROBE = (
    '<script>window.addEventListener("load", () => { for (const img of document.images) {'
    ' if (!img.complete || img.naturalWidth === 0) console.error("image did not load: " + img.src); }'
    ' console.log("probe: " + document.images.length + " images checked"); });</script>'
)


@pytest.mark.parametrize("page", ["index", "environment"])
def test_a_browser_shows_the_page_without_errors(site, page, tmp_path):
    if CHROMIUM is None:
        pytest.skip("chromium is not installed")
    original = site / f"{page}.html"
    probe = original.with_name(f"{page}.probe.html")  # beside the page, so its relative links hold
    probe.write_text(original.read_text(encoding="utf-8").replace("<head>", "<head>" + PROBE, 1), encoding="utf-8")
    screenshot = tmp_path / f"{page}.png"
    done = subprocess.run(
        [
            CHROMIUM,
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--no-first-run",
            f"--user-data-dir={tmp_path / 'profile'}",
            "--enable-logging=stderr",
            "--v=0",
            "--window-size=1280,1600",
            f"--screenshot={screenshot}",
            probe.as_uri(),
        ],
        capture_output=True,
        text=True,
        timeout=BROWSER_TIMEOUT_S,
    )
    console = [line.split("] ", 1)[-1] for line in done.stderr.splitlines() if ":CONSOLE" in line]
    assert any(message.startswith('"probe: ') for message in console), (
        f"the page did not finish loading:\n{done.stderr[-3000:]}"
    )
    problems = [message for message in console if not message.startswith('"probe: ')]
    assert not problems, f"{page}.html: " + "\n".join(problems)
    assert screenshot.is_file() and screenshot.stat().st_size > 20_000, "no screenshot, or a blank one"


def test_the_site_loads_nothing_from_another_host(site):
    """Every script, stylesheet and image of every page is a file of the build (MathJax included),
    so that the site shows the same offline, and no page links to an editor on another host."""
    foreign = []
    for path in site.rglob("*.html"):
        parser = _Links()
        parser.feed(path.read_text(encoding="utf-8"))
        for tag, key, url in parser.links:
            if tag in ("script", "img", "link") and (urlsplit(url).scheme or url.startswith("//")):
                foreign.append(f"{path.relative_to(site)}: <{tag} {key}={url!r}>")
            if tag == "a" and "/edit/" in url:
                foreign.append(f"{path.relative_to(site)}: <a href={url!r}>")
    assert not foreign, "\n".join(foreign)
    assert (site / "_static" / "mathjax" / "tex-chtml.js").is_file()


def chromium_dom(page: Path, profile: Path) -> str:
    """The DOM of a page of the site after its scripts have run, as headless Chromium shows it with
    every host name unresolvable (so offline)."""
    done = subprocess.run(
        [
            CHROMIUM,
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--no-first-run",
            f"--user-data-dir={profile}",
            "--host-resolver-rules=MAP * ~NOTFOUND",
            "--virtual-time-budget=20000",
            "--dump-dom",
            page.as_uri(),
        ],
        capture_output=True,
        text=True,
        timeout=BROWSER_TIMEOUT_S,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    return done.stdout


@pytest.mark.parametrize("page", ["physics", "guides/identification", "environment"])
def test_the_maths_renders_offline(site, page, tmp_path):
    """MathJax, shipped with the site, typesets every formula of a page in a browser that reaches no
    other host: one ``mjx-container`` per maths element, the headings' maths in the side menu too."""
    if CHROMIUM is None:
        pytest.skip("chromium is not installed")
    formulas = (site / f"{page}.html").read_text(encoding="utf-8").count('class="math notranslate nohighlight"')
    assert formulas > 5  # the page has maths, inline and displayed
    dom = chromium_dom(site / f"{page}.html", tmp_path / "profile")
    assert dom.count("<mjx-container") == formulas, "MathJax did not typeset every formula offline"
    if page == "physics":  # a heading with maths, in the page's table of contents
        toc = dom[dom.index('class="toc-tree"') :]
        entry = toc[toc.index("5.2 The leg") :]
        assert "<mjx-container" in entry[: entry.index("</a>")]


def test_the_environment_page_opens_with_its_summary(site):
    """The environment page opens, as Gymnasium's pages do, with a box of its spaces, import and id
    (read from the environment), then the card's Description; its reward is typeset, every weight
    and scale with its symbol."""
    import dataclasses

    import gymnasium as gym

    from stewart_env.tasks import TASKS, RewardWeights

    text = html.unescape(re.sub(r"<[^>]+>", "", (site / "environment.html").read_text(encoding="utf-8")))
    body = text[text.index("The environment: StewartPlatform-v1¶") :]
    description = body.index("Description¶")
    summary = body[:description]
    env = gym.make("StewartPlatform-v1")
    assert str(env.action_space) in summary
    for task in TASKS:
        assert str(gym.make("StewartPlatform-v1", task=task).observation_space) in summary
    assert 'gymnasium.make("StewartPlatform-v1")' in summary
    assert body.index("Action Space¶") > description
    rewards = body[body.index("The reward in symbols¶") : body.index("Starting State¶")]
    for field in dataclasses.fields(RewardWeights):
        assert field.name in rewards, f"the reward's symbols leave out {field.name}"
    assert rewards.count("\\(") > 10  # the symbols are maths, not plain text


def test_the_extras_table_is_pyproject_s(site):
    """getting-started's table of the extras lists each extra of pyproject.toml with its
    requirements, in pyproject's order."""
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10
        tomllib = pytest.importorskip("tomli")

    declared = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    page = (site / "getting-started.html").read_text(encoding="utf-8")
    table = page[page.index('<th class="head"><p>extra</p></th>') :]  # the rows after its header
    table = table[: table.index("</table>")]
    rows = re.findall(r"<tr[^>]*>(.*?)</tr>", table, flags=re.S)
    cells = [
        [html.unescape(re.sub(r"<[^>]+>", "", cell)) for cell in re.findall(r"<td>(.*?)</td>", row, flags=re.S)]
        for row in rows
    ]
    assert [row[0] for row in cells] == list(declared)
    for extra, purpose, installs in cells:
        assert purpose.strip(), f"the extra {extra} has no purpose"
        assert [r.strip() for r in installs.split(",")] == declared[extra]


# --- the pages run as written -----------------------------------------------------------------


@pytest.fixture(scope="module")
def pages_run(tmp_path_factory):
    return run_documents([DOCS / f"{page}.md" for page in site_pages()], tmp_path_factory.mktemp("pages"))


def test_every_block_runs(pages_run):
    if pages_run.failure is not None:
        pytest.fail(f"{type(pages_run.failure).__name__}: {pages_run.failure}")


def test_the_long_convention_is_stated(pages_run):
    states_the_long_convention(pages_run, "tests/docs/test_site.py")


def test_snippets_write_what_they_say(pages_run):
    promised = snippets_write_what_they_say(pages_run)
    assert any(path.endswith(".mp4") for _, path in promised), "no snippet records a video"


def test_the_quick_start_video_shows_a_controller_holding_the_platform(pages_run):
    # getting-started.md records the PD baseline for a whole set-point episode: 500 frames at the
    # environment's 100 fps, where the 20k-step agent's video ends with its first failure.
    imageio_ffmpeg = pytest.importorskip("imageio_ffmpeg")
    assert pages_run.failure is None, "an earlier block failed"
    frames, seconds = imageio_ffmpeg.count_frames_and_secs(str(pages_run.cwd / "videos/pd/rl-video-episode-0.mp4"))
    assert frames == 500 and seconds == pytest.approx(5.0, abs=0.05)  # the container's rounding of 500/100 s


def test_snippet_figures(pages_run):
    assert snippet_figures(pages_run) > 0, "no snippet states a figure of its table"


def test_demo_table(pages_run):
    block, table = block_and_text_table(pages_run, "stewart-env demo")
    printed = [row for out in block.outputs.values() for t in aligned_tables(out) for row in t]
    compare_table(table, printed, ("controller", "model"), f"{block.document}:{block.end + 1}, demo table")


def test_tracking_table(pages_run):
    block, table = block_and_table(pages_run, "stewart-env evaluate --policy pd-gc ct")
    assert all("--task tracking" in command for command in block.outputs)
    printed = [row for out in block.outputs.values() for t in markdown_tables(out) for row in t]
    compare_table(table, printed, ("controller", "model"), f"{block.document}:{block.end + 1}, tracking table")

    # the prose above the table: the ratios between these rows, on each plant
    def rms(controller, plant, unit):
        row = next(r for r in printed if (r["controller"], r["model"]) == (controller, plant))
        return float(row[{"pos.": "RMS pos. err. (mm)", "ori.": "RMS ori. err. (mrad)"}[unit]])

    plants = {"classical": "improved", "improved": "classical"}  # plant -> the other model
    pd_over_ct = {
        unit: [rms("PD + gravity comp.", m, unit) / rms(f"CT ({m})", m, unit) for m in plants]
        for unit in ("pos.", "ori.")
    }
    mismatch = {
        unit: [rms(f"CT ({other})", m, unit) / rms(f"CT ({m})", m, unit) for m, other in plants.items()]
        for unit in ("pos.", "ori.")
    }
    claims = {
        r"(\S+)-(\S+) times more closely in position": pd_over_ct["pos."],
        r"\((\S+)-(\S+) times in orientation\)": pd_over_ct["ori."],
        r"its position error grows (\S+)-(\S+) times": mismatch["pos."],
        r"its orientation error (\S+)-(\S+) times": mismatch["ori."],
    }
    text = " ".join((ROOT / block.document).read_text().split())  # the prose's line breaks are not part of it
    for pattern, values in claims.items():
        stated = re.search(pattern, text)
        assert stated, f"{block.document}: the tracking prose no longer says {pattern!r}"
        for figure, value in zip(stated.groups(), sorted(values)):
            assert same_figure(figure, f"{value:.{len(figure.partition('.')[2])}f}"), (
                f"{block.document}: tracking prose {stated.group(0)!r}, the table gives {sorted(values)}"
            )


def test_case_study_table(pages_run):
    block, table = block_and_table(pages_run, "stewart-env reproduce")
    (command,) = block.outputs
    out = pages_run.cwd / shlex.split(command)[shlex.split(command).index("--out") + 1]
    (summary,) = markdown_tables((out / "summary.md").read_text())[:1]
    compare_table(table, summary, ("quantity",), f"{block.document}:{block.end + 1}, case-study table")
    # the two improved forms agree to rounding: the page and the command both say so
    stated = re.search(r"`improved` vs `improved_centroidal`: (\S+) relative", (ROOT / block.document).read_text())
    printed = re.search(r"improved vs improved_centroidal (\S+)", block.outputs[command])
    assert stated and printed and float(stated.group(1)) < 1e-12 and float(printed.group(1)) < 1e-12


def test_physics_snippet_numbers(pages_run):
    """The physics snippet's comment gives the holding forces; they are what it computes."""
    page = "docs/guides/physics-api.md"
    namespace = pages_run.namespaces.get((page, "The physics API"))
    assert namespace is not None and pages_run.failure is None, "the physics snippet did not run"
    stated = re.search(r"holding forces, N \((\d+)-(\d+) N\)", (ROOT / page).read_text())
    assert stated, "the physics snippet no longer states the holding forces"
    forces = namespace["F"]
    assert (round(forces.min()), round(forces.max())) == (int(stated.group(1)), int(stated.group(2)))


def test_the_environment_page_is_the_env_card(site):
    """The environment page shows the class docstring, inserted at build time: every section of the
    card and every argument of the configuration records, and no hand-kept copy in the page's source."""
    import inspect

    from stewart_env.envs import DEFAULTS, StewartPlatformEnv

    card = inspect.cleandoc(StewartPlatformEnv.__doc__)
    headings = re.findall(r"^#+ (.+)$", card, flags=re.M)
    assert len(headings) >= 8  # Description ... Version History
    source = (DOCS / "environment.md").read_text()
    assert "<!-- generated: env card -->" in source
    assert not [h for h in headings if re.search(rf"^#+ {re.escape(h)}$", source, flags=re.M)]
    html = (site / "environment.html").read_text(encoding="utf-8")
    parser = _Links()
    parser.feed(html)
    for heading in headings:
        anchor = re.sub(r"[^\w\- ]", "", heading.lower()).replace(" ", "-")
        assert anchor in parser.ids, f"the environment page has no section {heading!r}"
    for name in DEFAULTS:
        assert f'<span class="pre">{name}</span>' in html, f"the environment page does not show the argument {name}"
