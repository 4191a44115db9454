"""The documentation stays true to the code: links resolve, the physics page's tables name code
and tests that exist, every kernel names the section of the physics page it implements, and no
project file points at a document outside the repository."""

import ast
import importlib
import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PHYSICS = ROOT / "docs" / "physics.md"
KERNELS = ROOT / "stewart_env" / "dynamics" / "kernels.py"
#: The compiled kernels' sources by the module name the physics page's function table gives them:
#: the one implementation of the physics (kernels.hpp) and of the integrator (rk4.hpp).
CPP_SOURCES = {
    "kernels": ROOT / "stewart_env" / "_core" / "cpp" / "physics" / "kernels.hpp",
    "rk4": ROOT / "stewart_env" / "_core" / "cpp" / "physics" / "rk4.hpp",
    "regressor": ROOT / "stewart_env" / "_core" / "cpp" / "identification" / "regressor.hpp",
}
CODE_MODULES = {
    "kernels": "stewart_env.dynamics.kernels",
    "model": "stewart_env.dynamics.model",
    "kinematics": "stewart_env.kinematics",
    "rk4": "stewart_env.dynamics.rk4",
    "workspace": "stewart_env.dynamics.workspace",
    "regressor": "stewart_env.identification.regressor",
}
# Written in two pieces so that this file does not match its own search.
OUTSIDE_DOCUMENTS = ["MODEL" + ".md", "../" + "shared", "/work/" + "shared"]


def tracked_files():
    try:
        out = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        pytest.skip("not a git checkout")
    return [ROOT / name for name in out.decode().split("\0") if name]


def markdown_files():
    """The README and the site's pages (the studies' outputs under docs/figures are not pages)."""
    pages = [
        p
        for p in (ROOT / "docs").rglob("*.md")
        if p.relative_to(ROOT / "docs").parts[0] not in ("figures", "_build", "_generated")
    ]
    return [ROOT / "README.md", *sorted(pages)]


def prose(text):
    """Markdown without fenced code blocks and inline code spans, where brackets are not links."""
    text = re.sub(r"^```.*?^```", "", text, flags=re.S | re.M)
    return re.sub(r"`[^`\n]*`", "", text)


def slug(heading):
    """GitHub's anchor of a heading: lower case, punctuation dropped, spaces to hyphens."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def section(text, heading):
    """The text under a heading up to the next heading of the same or a higher level."""
    level = heading.split(" ")[0]
    start = text.index(heading + "\n")
    end = re.search(rf"^#{{1,{len(level)}}} ", text[start + len(heading) :], flags=re.M)
    return text[start : start + len(heading) + end.start()] if end else text[start:]


def first_column_names(table):
    """Backticked names in the first column of a Markdown table (header and rule skipped)."""
    names = []
    for line in table.splitlines():
        cells = line.split("|")
        if line.startswith("|") and len(cells) > 2 and not set(cells[1].strip()) <= set("-"):
            names += re.findall(r"`([^`]+)`", cells[1])
    return names


def cpp_functions(path):
    """{name: comment} of every function defined at the top level of a C++ source (its namespace's
    body is not indented), with the ``//`` comment lines right above it joined into one text."""
    text = path.read_text()
    pattern = r'((?:^//.*\n)*)^(?:template <.*>\n)?(?:extern "C" )?(?:inline|constexpr)\b[^(;={}]*?\b(\w+)\('
    return {
        m.group(2): " ".join(line[2:].strip() for line in m.group(1).splitlines())
        for m in re.finditer(pattern, text, flags=re.M)
    }


def cpp_structs(path):
    """Names of the structs a C++ source defines."""
    return re.findall(r"^struct (\w+) \{", path.read_text(), flags=re.M)


def test_cpp_functions_are_found():
    """The parser of the C++ sources finds their functions, comments included."""
    functions = cpp_functions(CPP_SOURCES["kernels"])
    assert {"cross", "leg_frame", "forward_one", "forward_batch", "offset_of"} <= set(functions)
    assert "paper eq. 13" in functions["jacobian_row"]
    assert {"rollout_row", "constant_forces", "law_jacobian"} <= set(cpp_functions(CPP_SOURCES["rk4"]))


def test_no_tracked_file_points_at_a_document_outside_the_repository():
    offenders = []
    for path in tracked_files():
        if not path.is_file():
            continue  # deleted in the working tree
        data = path.read_bytes()
        offenders += [f"{path.relative_to(ROOT)}: {p}" for p in OUTSIDE_DOCUMENTS if p.encode() in data]
    assert not offenders


@pytest.mark.parametrize("page", markdown_files(), ids=lambda p: str(p.relative_to(ROOT)))
def test_relative_links_resolve(page):
    text = page.read_text()
    targets = re.findall(r"\]\(([^)\s]+)\)", prose(text)) + re.findall(r"^\[[^\]]+\]:\s*(\S+)", text, flags=re.M)
    anchors = {slug(h) for h in re.findall(r"^#+ (.+)$", prose(text), flags=re.M)}
    broken = []
    for target in targets:
        if re.match(r"[a-z]+:", target):
            continue  # http(s), mailto: outside the repository by intent
        path, _, anchor = target.partition("#")
        if path.startswith("_generated/"):
            continue  # drawn when the site is built; tests/docs/test_site.py checks the built page's images
        if path and not (page.parent / path).exists():
            broken.append(target)
        elif not path and anchor not in anchors:
            broken.append(target)
    assert not broken


# Hosts that do not serve this project: a link to them is dead to a reader of the checkout.
FOREIGN_HOSTS = ("readthedocs", "github.com/stewart-env", "raw.githubusercontent.com")
IMAGE_SUFFIXES = (".png", ".svg", ".jpg", ".gif")


def test_readme_links_and_images_are_files_of_the_repository():
    """Every link and image of README.md names a file or folder of the repository, and every
    ``#anchor`` a heading of the page it names; the only web addresses are those of code blocks
    (package indexes), none of them a host that does not serve this project."""
    text = (ROOT / "README.md").read_text()
    assert not [host for host in FOREIGN_HOSTS if host in text]
    links = re.findall(r"(!?)\[[^\]]*\]\(([^)\s]+)\)", prose(text))
    autolinks = re.findall(r"<(https?://[^>]+)>", prose(text))
    assert len(links) > 20  # the links were found: the README links its pages and results
    assert not autolinks and not [url for _, url in links if re.match(r"[a-z]+:", url)]
    broken = []
    for image, url in links:
        path, _, anchor = url.partition("#")
        target = ROOT / path
        if not target.exists():
            broken.append(f"{url}: no such file")
        elif image and not (target.is_file() and target.suffix in IMAGE_SUFFIXES):
            broken.append(f"{url}: not an image")
        elif anchor and (
            target.suffix != ".md"
            or anchor not in {slug(h) for h in re.findall(r"^#+ (.+)$", prose(target.read_text()), flags=re.M)}
        ):
            broken.append(f"{url}: no heading #{anchor} in {path}")
    assert not broken


def test_readme_builds_the_site_as_its_page_says():
    """The README's one-line build of the site is the command of the site's page on building it."""
    command = r"python -m sphinx [^`\n]+"
    readme = re.findall(command, " ".join((ROOT / "README.md").read_text().split()))
    layout = re.findall(command, (ROOT / "docs" / "layout.md").read_text())
    assert readme and readme == layout


def test_every_function_in_the_physics_table_exists_and_every_kernel_is_listed():
    """Every function of the compiled kernels (kernels.hpp, rk4.hpp) and of their Python faces
    (kernels.py, rk4.py) has a row in the physics page's function table, and every row names a
    function or struct of those sources or an attribute of the module it names."""
    table = section(PHYSICS.read_text(), "### 3.2 Functions")
    listed = first_column_names(table)
    assert len(listed) > 30  # the table was found and parsed
    missing = []
    for name in listed:
        module, _, attr = name.partition(".")
        cpp = CPP_SOURCES.get(module)
        if cpp is not None and (attr in cpp_functions(cpp) or attr in cpp_structs(cpp)):
            continue
        if not hasattr(importlib.import_module(CODE_MODULES[module]), attr):
            missing.append(name)
    assert not missing
    for module, path in (("kernels", KERNELS), ("rk4", KERNELS.with_name("rk4.py"))):
        functions = [n.name for n in ast.parse(path.read_text()).body if isinstance(n, ast.FunctionDef)]
        functions += list(cpp_functions(CPP_SOURCES[module]))
        assert sorted(set(functions) - {n.partition(".")[2] for n in listed if n.startswith(module + ".")}) == []


def test_every_code_name_in_the_symbol_table_occurs_in_the_code():
    table = section(PHYSICS.read_text(), "### 3.1 Quantities")
    names = first_column_names(table)
    assert len(names) > 50  # the table was found and parsed
    source = "".join(importlib.import_module(m).__loader__.get_source(m) for m in CODE_MODULES.values())
    source += "".join(path.read_text() for path in CPP_SOURCES.values())

    def occurs(word):
        return re.search(rf"(?<![\w']){re.escape(word)}(?![\w'])", source) is not None

    # a vector's components are named with the suffixes 0, 1, 2; the table gives the stem
    assert [n for n in names if not (occurs(n) or occurs(n + "0"))] == []


def test_every_test_the_physics_page_cites_exists():
    cited = re.findall(r"`(tests/[\w/]+\.py)::(\w+)`", PHYSICS.read_text())
    assert len(cited) >= 10
    missing = [
        f"{f}::{t}"
        for f, t in cited
        if not (ROOT / f).is_file() or not re.search(rf"^def {t}\(", (ROOT / f).read_text(), flags=re.M)
    ]
    assert not missing


def test_code_docstrings_cite_sections_that_exist():
    headings = set(re.findall(r"^#{2,3} (\d+(?:\.\d+)?)\.? ", PHYSICS.read_text(), flags=re.M))
    tree = ast.parse(KERNELS.read_text())
    undocumented = [
        n.name
        for n in tree.body
        if isinstance(n, ast.FunctionDef) and "docs/physics.md" not in (ast.get_docstring(n) or "")
    ]
    undocumented += [
        f"{module}.{name}"
        for module, path in CPP_SOURCES.items()
        for name, comment in cpp_functions(path).items()
        if "docs/physics.md" not in comment
    ]
    assert not undocumented
    cited = []
    sources = [importlib.import_module(m).__loader__.get_source(m) for m in CODE_MODULES.values()]
    # a C++ comment's lines joined, so that a citation broken over two lines is read whole
    sources += [
        " ".join(re.sub(r"^\s*// ?", "", line) for line in path.read_text().splitlines())
        for path in CPP_SOURCES.values()
    ]
    for source in sources:
        for ref in re.findall(r"docs/physics\.md\)? (sections? [0-9][0-9.,\- and]*)", source):
            cited += re.findall(r"(?<![\w.])\d+(?:\.\d+)?", ref)
    assert len(cited) > 30
    assert sorted(set(cited) - headings) == []


def test_readme_switch_table_is_the_code_table():
    """The README's table of the switches c1-c4 says what stewart_env.dynamics.model.SIMPLIFICATIONS says."""
    from stewart_env.dynamics.model import SIMPLIFICATIONS

    rows = re.findall(r"^\| `(c\d)` \| (.+?) \|$", (ROOT / "README.md").read_text(), flags=re.M)
    assert dict(rows) == SIMPLIFICATIONS
    assert len(rows) == len(SIMPLIFICATIONS)  # no switch listed twice


def test_the_parameter_table_and_the_packed_layout_name_the_same_keys():
    from stewart_env.dynamics.kernels import PACKED_LAYOUT

    table = first_column_names(section(PHYSICS.read_text(), "## 2. Parameters"))
    packed = [key for key, _ in PACKED_LAYOUT]
    # the table splits damping into its three coefficients; limits and home are the environment's
    assert [k for k in packed if k not in table and not any(t.startswith(k + ".") for t in table)] == []
    assert [
        t for t in table if t not in packed and t.partition(".")[0] not in packed and t not in ("limits", "home")
    ] == []


def test_every_kernel_names_its_paper_equations_or_says_it_has_none():
    tree = ast.parse(KERNELS.read_text())
    silent = [
        n.name
        for n in tree.body
        if isinstance(n, ast.FunctionDef)
        and not re.search(r"\beqs?\.\s+\d|no\s+paper\s+equation", ast.get_docstring(n) or "")
    ]
    silent += [
        f"{module}.{name}"
        for module, path in CPP_SOURCES.items()
        for name, comment in cpp_functions(path).items()
        if not re.search(r"\beqs?\.\s+\d|no\s+paper\s+equation", comment)
    ]
    assert silent == []
