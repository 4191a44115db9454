"""The README runs as written, and its numbers are what its commands print.

Every fenced block of README.md is taken in order, in one temporary working directory (so a
later block finds what an earlier one wrote), by its info string:

- ``bash``, ``sh`` or none: commands, each run by bash.  A ``# long: <why>`` line marks the next
  command as a long run: it is not run, but a ``stewart-env`` command's arguments are parsed and
  the repository files it names must exist.  ``pip install`` and ``python -m pytest`` commands
  are checked, not run: the install-and-test command must be the one ``.ci/run`` runs, the extras
  must exist, torch must be pinned, and a marker expression may name registered markers only.
- ``python``: run as a script (``__name__ == "__main__"``); the blocks under one heading share a
  namespace.  A comment ``# writes PATH`` names a file the block must leave, and
  ``# <column>: <value>`` a figure of the table it prints.
- ``yaml``: parsed; it must name exactly the keys of a shipped platform config, with its values.
- ``text``: an overview: each ``stewart-env <command>`` must have ``--help``, each listed
  directory must exist.

The tables printed by cheap, seeded commands (the demo, the tracking evaluation, the case study)
are compared with what those commands print now.
"""

from __future__ import annotations

import contextlib
import io
import math
import os
import re
import shlex
import subprocess
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest
import yaml

import stewart_env as se
from stewart_env.cli import build_parser, main

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
SHELL_TAGS = ("bash", "sh", "")
KNOWN_TAGS = SHELL_TAGS + ("python", "yaml", "text")
LONG_MARK = "# long:"
# a command run by the test, with its output, may take this long before it counts as hung
COMMAND_TIMEOUT_S = 300


@dataclass
class Block:
    tag: str
    text: str
    line: int  # of the opening fence, 1-based
    heading: str  # the nearest heading above the block
    end: int  # line of the closing fence
    outputs: dict[str, str] = field(default_factory=dict)  # command -> its stdout, for the commands run


def readme_blocks(text: str) -> list[Block]:
    blocks, heading, fence = [], "", None
    lines = text.splitlines()
    for number, line in enumerate(lines, 1):
        if fence is None:
            if line.startswith("```"):
                fence = (line[3:].strip(), number, [])
            elif re.match(r"#{1,6} ", line):
                heading = line.lstrip("#").strip()
        elif line.startswith("```"):
            tag, start, body = fence
            blocks.append(Block(tag, "\n".join(body) + "\n", start, heading, number))
            fence = None
        else:
            fence[2].append(line)
    assert fence is None, f"README.md:{fence[1]}: the fenced block is never closed"
    return blocks


def shell_commands(block: Block) -> list[tuple[str, str | None]]:
    """(command, reason it is long or None) for each command of a shell block; a trailing
    backslash continues a command on the next line."""
    commands, long_reason, pending = [], None, ""
    for line in block.text.splitlines():
        stripped = line.strip()
        if not pending and (not stripped or stripped.startswith("#")):
            if stripped.startswith(LONG_MARK):
                long_reason = stripped[len(LONG_MARK):].strip()
            continue
        if stripped.endswith("\\"):
            pending += stripped[:-1] + " "
            continue
        commands.append((pending + stripped, long_reason))
        pending, long_reason = "", None
    assert not pending, f"README.md:{block.line}: a command ends in a backslash"
    assert long_reason is None, f"README.md:{block.line}: '{LONG_MARK}' with no command after it"
    return commands


def ci_test_command() -> str:
    lines = [line.strip() for line in (ROOT / ".ci" / "run").read_text().splitlines()]
    commands = [line for line in lines if "pytest" in line and not line.startswith("#")]
    assert len(commands) == 1, f".ci/run: expected one line that runs pytest, found {commands}"
    return commands[0]


def check_pip(part: str, where: str) -> None:
    """A pip command of the README installs extras that exist, and torch only at the pinned version."""
    section = (ROOT / "pyproject.toml").read_text().split("[project.optional-dependencies]")[1].split("\n[")[0]
    extras = set(re.findall(r"^([\w-]+)\s*=", section, re.M))
    for word in shlex.split(part)[2:]:
        named = re.fullmatch(r"\.\[(.*)\]", word)
        if named:
            unknown = set(named.group(1).split(",")) - extras
            assert not unknown, f"{where}: extras {sorted(unknown)} are not in pyproject.toml ({sorted(extras)})"
        if word.startswith("torch"):
            assert word == "torch==2.13.0", f"{where}: torch must be pinned to the CPU build's 2.13.0, not {word!r}"


def check_pytest(part: str, where: str) -> None:
    """A test command is not run (the suite runs the README, not the other way round): the
    markers it selects must be registered."""
    argv = shlex.split(part)
    registered = set(re.findall(r'^\s*"(\w+):', (ROOT / "pyproject.toml").read_text(), re.M))
    if "-m" in argv[3:]:
        expression = argv[3:][argv[3:].index("-m") + 1]
        unknown = set(re.findall(r"\w+", expression)) - {"not", "and", "or"} - registered
        assert not unknown, f"{where}: {part!r} selects unregistered markers {sorted(unknown)}"


def check_long(command: str, where: str) -> None:
    """A long command is not run: its arguments must parse and the repository files it names exist."""
    argv = shlex.split(command, comments=True)
    if argv[0] == "stewart-env":
        old_cwd = os.getcwd()
        os.chdir(ROOT)  # where the README runs them, so that the files they name are found
        try:
            with contextlib.redirect_stderr(io.StringIO()) as error:
                build_parser().parse_args(argv[1:])
        except SystemExit:
            raise AssertionError(f"{where}: stewart-env does not accept {command!r}: {error.getvalue()}") from None
        finally:
            os.chdir(old_cwd)
    for word in argv:
        if word.startswith("configs/"):
            assert (ROOT / word).exists(), f"{where}: {word} does not exist in the repository"


def run_shell(command: str, cwd: Path, where: str) -> str:
    env = {**os.environ, "MPLBACKEND": "Agg"}
    done = subprocess.run(["bash", "-c", "set -eo pipefail\n" + command], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=COMMAND_TIMEOUT_S)
    assert done.returncode == 0, (f"{where}: {command!r} exited with {done.returncode}:\n"
                                  f"{done.stdout[-2000:]}\n{done.stderr[-3000:]}")
    return done.stdout


def run_shell_block(block: Block, cwd: Path) -> None:
    where = f"README.md:{block.line}"
    for command, long_reason in shell_commands(block):
        if long_reason is not None:
            check_long(command, where)
            continue
        parts = [part.strip() for part in command.split("&&")]
        if any(part.startswith("pip ") for part in parts) and any(part.startswith("python -m pytest") for part in parts):
            assert command == ci_test_command(), (f"{where}: the README's test command {command!r} is not "
                                                  f"the one .ci/run runs, {ci_test_command()!r}")
        for part in parts:
            if part.startswith("pip "):
                check_pip(part, where)
            elif part.startswith("python -m pytest"):
                check_pytest(part, where)
        rest = [part for part in parts if not part.startswith(("pip ", "python -m pytest"))]
        if rest:
            block.outputs[command] = run_shell(" && ".join(rest), cwd, where)


def check_yaml(block: Block) -> None:
    """The config overview names every key of the shipped config, no other, and its values."""
    shown = yaml.safe_load(block.text)
    shipped = se.load_platform("dasgupta1998").to_dict()

    def compare(a, b, path):
        if isinstance(a, dict):
            assert isinstance(b, dict) and set(a) == set(b), \
                f"README.md:{block.line}: keys of {path or 'the config'}: README {sorted(a)}, config {sorted(b)}"
            for key in a:
                compare(a[key], b[key], f"{path}.{key}".lstrip("."))
        elif "..." not in str(a) and not re.search(r"[a-z]", str(a)):  # a value written out in full
            shown_value, shipped_value = np.asarray(a, float), np.asarray(b, float)
            if shown_value.shape == (3,) and shipped_value.shape == (3, 3):  # a diagonal inertia
                assert np.array_equal(shipped_value, np.diag(np.diag(shipped_value))), \
                    f"README.md:{block.line}: {path} is written as a diagonal, but the config's is not diagonal"
                shipped_value = np.diag(shipped_value)
            # the README copies the config's decimals: equal up to float parsing
            assert shown_value == pytest.approx(shipped_value, rel=1e-12), \
                f"README.md:{block.line}: {path} is {a} in the README, {b} in the config"

    compare(shown, shipped, "")


def check_text(block: Block) -> None:
    for line in block.text.splitlines():
        command = re.match(r"stewart-env (\S+)", line)
        if command:
            # in-process: the parser is what the console script runs
            with contextlib.redirect_stdout(io.StringIO()), pytest.raises(SystemExit) as exit_:
                main([command.group(1), "--help"])
            assert exit_.value.code in (0, None), f"README.md:{block.line}: stewart-env {command.group(1)} --help failed"
        directory = re.match(r"([\w./]+/)\s", line)
        if directory:
            assert (ROOT / directory.group(1)).is_dir(), f"README.md:{block.line}: {directory.group(1)} does not exist"


@pytest.fixture(scope="module")
def readme_run(tmp_path_factory):
    """Every block of the README, run or checked in order; (blocks, namespaces, first failure)."""
    cwd = tmp_path_factory.mktemp("readme")
    blocks = readme_blocks(README.read_text())
    namespaces: dict[str, dict] = {}
    failure = None
    old_cwd = os.getcwd()
    os.chdir(cwd)
    try:
        for block in blocks:
            assert block.tag in KNOWN_TAGS, f"README.md:{block.line}: unknown block type {block.tag!r}"
            if block.tag in SHELL_TAGS:
                run_shell_block(block, cwd)
            elif block.tag == "python":
                # run as a script runs them, so that a snippet's `if __name__ == "__main__":` block runs
                namespace = namespaces.setdefault(block.heading, {"__name__": "__main__"})
                with contextlib.redirect_stdout(io.StringIO()) as out:
                    exec(compile(block.text, f"README.md:{block.line}", "exec"), namespace)
                block.outputs["python"] = out.getvalue()
            elif block.tag == "yaml":
                check_yaml(block)
            else:
                check_text(block)
    except Exception as err:  # the failing block's message is the report of test_every_block_runs
        failure = err
    finally:
        os.chdir(old_cwd)
    return blocks, namespaces, cwd, failure


def test_every_block_runs(readme_run):
    failure = readme_run[3]
    if failure is not None:
        pytest.fail(f"{type(failure).__name__}: {failure}")


def test_readme_states_the_long_convention(readme_run):
    blocks = readme_run[0]
    first_long = next(b for b in blocks if b.tag in SHELL_TAGS and LONG_MARK in b.text)
    text = README.read_text().splitlines()
    # within a screen of the first marked command
    nearby = "\n".join(text[max(0, first_long.line - 15):first_long.end + 15])
    assert f"`{LONG_MARK}" in nearby and "tests/test_readme.py" in nearby


def test_snippets_write_what_they_say(readme_run):
    """A snippet's `# writes PATH` comment (the videos of the quick start and of the environment)
    names a file it left behind."""
    blocks, cwd = readme_run[0], readme_run[2]
    assert readme_run[3] is None, "an earlier block failed"
    promised = [(b.line, path) for b in blocks if b.tag == "python" for path in re.findall(r"# writes (\S+)", b.text)]
    assert any(path.endswith(".mp4") for _, path in promised), "no snippet records a video"
    for line, path in promised:
        assert (cwd / path).is_file(), f"README.md:{line}: the snippet says it writes {path}, which does not exist"


# --- the numbers of the tables ---------------------------------------------------------------

def markdown_tables(text: str) -> list[list[dict[str, str]]]:
    """The pipe tables of ``text``, each a list of rows {header: cell}."""
    tables, rows = [], []
    for line in text.splitlines() + [""]:
        if line.startswith("|"):
            rows.append([cell.strip() for cell in line.strip().strip("|").split("|")])
            continue
        if len(rows) >= 2:
            header = rows[0]
            tables.append([dict(zip(header, row)) for row in rows[2:]])
        rows = []
    return tables


# a measured figure; a leg's number is a label, compared as text
NUMBER = re.compile(r"(?<!leg )-?\d+(?:\.\d+)?(?:e[-+]?\d+)?")
# counts, compared exactly
EXACT_COLUMNS = ("episodes", "success")
# Below this (in the table's unit: mm, mrad, %) a figure is float rounding error, whose digits
# depend on the CPU's floating-point instruction set: only that it stays this small is compared.
ROUNDING_LEVEL = 1e-4


def same_figure(readme: str, printed: str) -> bool:
    """Equal text, and numbers equal to within one unit of the README's last printed digit (another
    CPU may round a seeded episode's last digit the other way)."""
    if NUMBER.sub("#", readme) != NUMBER.sub("#", printed):
        return False
    for a, b in zip(NUMBER.findall(readme), NUMBER.findall(printed)):
        x, y = float(a), float(b)
        if abs(x) < ROUNDING_LEVEL and abs(y) < ROUNDING_LEVEL:
            continue
        mantissa = a.split("e")[0]
        decimals = len(mantissa.split(".")[1]) if "." in mantissa else 0
        exponent = int(a.split("e")[1]) if "e" in a else 0
        if not math.isclose(x, y, abs_tol=1.01 * 10.0 ** (exponent - decimals)):
            return False
    return True


def compare_table(readme_rows, printed_rows, keys, where):
    index = {tuple(row[k] for k in keys): row for row in printed_rows}
    assert len(readme_rows) == len(index), f"{where}: {len(readme_rows)} rows, the command prints {len(index)}"
    for row in readme_rows:
        key = tuple(row[k] for k in keys)
        assert key in index, f"{where}: the command prints no row {key}"
        for column, cell in row.items():
            assert column in index[key], f"{where}: the command prints no column {column!r}"
            same = cell == index[key][column] if column in EXACT_COLUMNS else same_figure(cell, index[key][column])
            assert same, \
                f"{where}: {key}, {column}: README {cell}, the command prints {index[key][column]}"


def block_and_table(readme_run, command_start):
    """The block whose command starts with ``command_start``, and the README table right after it."""
    blocks = readme_run[0]
    assert readme_run[3] is None, "an earlier block failed"
    block = next(b for b in blocks if any(c.startswith(command_start) for c, _ in shell_commands(b))
                 if b.tag in SHELL_TAGS)
    after = "\n".join(README.read_text().splitlines()[block.end:])
    return block, markdown_tables(after)[0]


def test_demo_table(readme_run):
    block, table = block_and_table(readme_run, "stewart-env demo")
    printed = [row for out in block.outputs.values() for t in markdown_tables(out) for row in t]
    compare_table(table, printed, ("controller", "model"), f"README.md:{block.end + 1}, demo table")


def test_tracking_table(readme_run):
    block, table = block_and_table(readme_run, "stewart-env evaluate --policy pd-gc ct")
    assert all("--task tracking" in command for command in block.outputs)
    printed = [row for out in block.outputs.values() for t in markdown_tables(out) for row in t]
    compare_table(table, printed, ("controller", "model"), f"README.md:{block.end + 1}, tracking table")

    # the prose above the table: the ratios between these rows, on each plant
    def rms(controller, plant, unit):
        row = next(r for r in printed if (r["controller"], r["model"]) == (controller, plant))
        return float(row[{"pos.": "RMS pos. err. (mm)", "ori.": "RMS ori. err. (mrad)"}[unit]])

    plants = {"classical": "improved", "improved": "classical"}  # plant -> the other model
    pd_over_ct = {unit: [rms("PD + gravity comp.", m, unit) / rms(f"CT ({m})", m, unit) for m in plants]
                  for unit in ("pos.", "ori.")}
    mismatch = {unit: [rms(f"CT ({other})", m, unit) / rms(f"CT ({m})", m, unit) for m, other in plants.items()]
                for unit in ("pos.", "ori.")}
    claims = {
        r"(\S+)-(\S+) times more closely in position": pd_over_ct["pos."],
        r"\((\S+)-(\S+) times in orientation\)": pd_over_ct["ori."],
        r"its position error grows (\S+)-(\S+) times": mismatch["pos."],
        r"its orientation error (\S+)-(\S+) times": mismatch["ori."],
    }
    text = " ".join(README.read_text().split())  # the prose's line breaks are not part of it
    for pattern, values in claims.items():
        stated = re.search(pattern, text)
        assert stated, f"README: the tracking prose no longer says {pattern!r}"
        for figure, value in zip(stated.groups(), sorted(values)):
            assert same_figure(figure, f"{value:.{len(figure.partition('.')[2])}f}"), \
                f"README: tracking prose {stated.group(0)!r}, the table gives {sorted(values)}"


def test_case_study_table(readme_run):
    block, table = block_and_table(readme_run, "stewart-env reproduce")
    (command,) = block.outputs
    out = readme_run[2] / shlex.split(command)[shlex.split(command).index("--out") + 1]
    (summary,) = markdown_tables((out / "summary.md").read_text())[:1]
    compare_table(table, summary, ("quantity",), f"README.md:{block.end + 1}, case-study table")
    # the two improved forms agree to rounding: the README and the command both say so
    stated = re.search(r"`improved` vs `improved_centroidal`: (\S+) relative", README.read_text())
    printed = re.search(r"improved vs improved_centroidal (\S+)", block.outputs[command])
    assert stated and printed and float(stated.group(1)) < 1e-12 and float(printed.group(1)) < 1e-12


def test_snippet_figures(readme_run):
    """A snippet that prints a table states a figure of it as `# <column>: <value>`."""
    assert readme_run[3] is None, "an earlier block failed"
    stated = [(b, m) for b in readme_run[0] if b.tag == "python"
              for m in re.finditer(r"# ([^#\n]+): (\S+)$", b.text, re.M)]
    assert stated, "no snippet states a figure of its table"
    for block, match in stated:
        (row,) = markdown_tables(block.outputs["python"])[0]
        column, figure = match.groups()
        assert same_figure(figure, row[column]), \
            f"README.md:{block.line}: the snippet says {column} {figure}, it prints {row[column]}"


def test_physics_snippet_numbers(readme_run):
    """The physics snippet's comment gives the holding forces; they are what it computes."""
    namespace = readme_run[1].get("The physics API")
    assert namespace is not None and readme_run[3] is None, "the physics snippet did not run"
    stated = re.search(r"holding forces, N \((\d+)-(\d+) N\)", README.read_text())
    assert stated, "the physics snippet no longer states the holding forces"
    forces = namespace["F"]
    assert (round(forces.min()), round(forces.max())) == (int(stated.group(1)), int(stated.group(2)))
