"""Run the fenced blocks of Markdown documents as written: the README and the site's pages.

Every fenced block of the given documents is taken in order, in one temporary working directory
(so a later block, or a later page, finds what an earlier one wrote), by its info string:

- a block whose first line is ``# file: PATH``: written to PATH (a file of a package a page
  builds); the working directory is on ``sys.path`` while the blocks run, so later blocks import it.
- ``bash``, ``sh`` or none: commands, each run by bash.  A ``# long: <why>`` line marks the next
  command as a long run: it is not run, but a ``stewart-env`` command's arguments are parsed and
  the repository files it names must exist.  ``pip install`` and ``python -m pytest`` commands
  are checked, not run: the install-and-test command must be the one ``.ci/run`` runs, the extras
  must exist, torch must be pinned, and a marker expression may name registered markers only.
- ``python``: run as a script (``__name__ == "__main__"``); the blocks under one heading of one
  document share a namespace.  A comment ``# writes PATH`` names a file the block must leave, and
  ``# <column>: <value>`` a figure of the table it prints.
- ``yaml``: parsed; it must name exactly the keys of a shipped platform config, with its values,
  or, keyed by the environment's id, be part of a shipped agent config (configs/agents).
- ``text``: an overview: each ``stewart-env <command>`` must have ``--help``, each listed
  directory must exist.
- ``{name}``: a MyST directive of a site page (a table of contents, an include): not code.

The tables printed by cheap, seeded commands are compared with the document's tables by the
tests that use this module (``same_figure``, ``compare_table``).
"""

from __future__ import annotations

import contextlib
import io
import math
import os
import re
import shlex
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest
import yaml

import stewart_env as se
from stewart_env.cli import build_parser, main
from stewart_env.registration import ENV_ID

ROOT = Path(__file__).resolve().parents[1]
SHELL_TAGS = ("bash", "sh", "")
KNOWN_TAGS = SHELL_TAGS + ("python", "yaml", "text")
LONG_MARK = "# long:"
FILE_MARK = "# file:"
# a command run by the test, with its output, may take this long before it counts as hung
COMMAND_TIMEOUT_S = 300


@dataclass
class Block:
    tag: str
    text: str
    line: int  # of the opening fence, 1-based
    heading: str  # the nearest heading above the block
    end: int  # line of the closing fence
    document: str = ""  # the document's path relative to the repository
    outputs: dict[str, str] = field(default_factory=dict)  # command -> its stdout, for the commands run

    @property
    def where(self) -> str:
        return f"{self.document}:{self.line}"


def markdown_blocks(text: str, document: str = "README.md") -> list[Block]:
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
            blocks.append(Block(tag, "\n".join(body) + "\n", start, heading, number, document))
            fence = None
        else:
            fence[2].append(line)
    assert fence is None, f"{document}:{fence[1]}: the fenced block is never closed"
    return blocks


def shell_commands(block: Block) -> list[tuple[str, str | None]]:
    """(command, reason it is long or None) for each command of a shell block; a trailing
    backslash continues a command on the next line."""
    commands, long_reason, pending = [], None, ""
    for line in block.text.splitlines():
        stripped = line.strip()
        if not pending and (not stripped or stripped.startswith("#")):
            if stripped.startswith(LONG_MARK):
                long_reason = stripped[len(LONG_MARK) :].strip()
            continue
        if stripped.endswith("\\"):
            pending += stripped[:-1] + " "
            continue
        commands.append((pending + stripped, long_reason))
        pending, long_reason = "", None
    assert not pending, f"{block.where}: a command ends in a backslash"
    assert long_reason is None, f"{block.where}: '{LONG_MARK}' with no command after it"
    return commands


def ci_test_command() -> str:
    lines = [line.strip() for line in (ROOT / ".ci" / "run").read_text().splitlines()]
    commands = [line for line in lines if "pytest" in line and not line.startswith("#")]
    assert len(commands) == 1, f".ci/run: expected one line that runs pytest, found {commands}"
    return commands[0]


def check_pip(part: str, where: str) -> None:
    """A pip command installs extras that exist, and torch only at the pinned version."""
    section = (ROOT / "pyproject.toml").read_text().split("[project.optional-dependencies]")[1].split("\n[")[0]
    extras = set(re.findall(r"^([\w-]+)\s*=", section, re.M))
    for word in shlex.split(part)[2:]:
        named = re.fullmatch(r"\.\[(.*)\]", word)
        if named:
            unknown = set(named.group(1).split(",")) - extras
            assert not unknown, f"{where}: extras {sorted(unknown)} are not in pyproject.toml ({sorted(extras)})"
        if word.startswith("torch"):
            assert word == "torch==2.13.0", f"{where}: torch must be pinned to 2.13.0, not {word!r}"


def check_pytest(part: str, where: str) -> None:
    """A test command is not run (the suite runs the documents, not the other way round): the
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
        os.chdir(ROOT)  # where the documents run them, so that the files they name are found
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
    done = subprocess.run(
        ["bash", "-c", "set -eo pipefail\n" + command],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=COMMAND_TIMEOUT_S,
    )
    assert done.returncode == 0, (
        f"{where}: {command!r} exited with {done.returncode}:\n{done.stdout[-2000:]}\n{done.stderr[-3000:]}"
    )
    return done.stdout


def run_shell_block(block: Block, cwd: Path) -> None:
    for command, long_reason in shell_commands(block):
        if long_reason is not None:
            check_long(command, block.where)
            continue
        parts = [part.strip() for part in command.split("&&")]
        if any(part.startswith("pip ") for part in parts) and any(
            part.startswith("python -m pytest") for part in parts
        ):
            assert command == ci_test_command(), (
                f"{block.where}: the test command {command!r} is not the one .ci/run runs, {ci_test_command()!r}"
            )
        for part in parts:
            if part.startswith("pip "):
                check_pip(part, block.where)
            elif part.startswith("python -m pytest"):
                check_pytest(part, block.where)
        rest = [part for part in parts if not part.startswith(("pip ", "python -m pytest"))]
        if rest:
            block.outputs[command] = run_shell(" && ".join(rest), cwd, block.where)


def check_yaml(block: Block) -> None:
    """The config overview names every key of the shipped config, no other, and its values; an
    excerpt of an agent config (keyed by the environment's id) is part of a shipped one."""
    shown = yaml.safe_load(block.text)
    if isinstance(shown, dict) and set(shown) == {ENV_ID}:
        configs = sorted((ROOT / "configs" / "agents").glob("*.yml"))
        assert any(_contains(yaml.safe_load(c.read_text()), shown) for c in configs), (
            f"{block.where}: the excerpt is part of no shipped agent config"
        )
        return
    shipped = se.load_platform("dasgupta1998").to_dict()

    def compare(a, b, path):
        if isinstance(a, dict):
            assert isinstance(b, dict) and set(a) == set(b), (
                f"{block.where}: keys of {path or 'the config'}: shown {sorted(a)}, config {sorted(b)}"
            )
            for key in a:
                compare(a[key], b[key], f"{path}.{key}".lstrip("."))
        elif "..." not in str(a) and not re.search(r"[a-z]", str(a)):  # a value written out in full
            shown_value, shipped_value = np.asarray(a, float), np.asarray(b, float)
            if shown_value.shape == (3,) and shipped_value.shape == (3, 3):  # a diagonal inertia
                assert np.array_equal(shipped_value, np.diag(np.diag(shipped_value))), (
                    f"{block.where}: {path} is written as a diagonal, but the config's is not diagonal"
                )
                shipped_value = np.diag(shipped_value)
            # the document copies the config's decimals: equal up to float parsing
            assert shown_value == pytest.approx(shipped_value, rel=1e-12), (
                f"{block.where}: {path} is {a} in the document, {b} in the config"
            )

    compare(shown, shipped, "")


def _contains(whole, part) -> bool:
    """Whether ``part`` is ``whole`` with some mapping keys left out (values equal)."""
    if isinstance(part, dict):
        return isinstance(whole, dict) and all(k in whole and _contains(whole[k], v) for k, v in part.items())
    return whole == part


def check_text(block: Block) -> None:
    for line in block.text.splitlines():
        command = re.match(r"stewart-env (\S+)", line)
        if command:
            # in-process: the parser is what the console script runs
            with contextlib.redirect_stdout(io.StringIO()), pytest.raises(SystemExit) as exit_:
                main([command.group(1), "--help"])
            assert exit_.value.code in (0, None), f"{block.where}: stewart-env {command.group(1)} --help failed"
        directory = re.match(r"([\w./]+/)\s", line)
        if directory:
            assert (ROOT / directory.group(1)).is_dir(), f"{block.where}: {directory.group(1)} does not exist"


def write_file_block(block: Block, cwd: Path) -> None:
    """A ``# file: PATH`` block: its text (the marker line included) written to PATH under cwd."""
    path = block.text.splitlines()[0][len(FILE_MARK) :].strip()
    assert path and not Path(path).is_absolute() and ".." not in Path(path).parts, (
        f"{block.where}: '{FILE_MARK}' needs a relative path inside the working directory, got {path!r}"
    )
    (cwd / path).parent.mkdir(parents=True, exist_ok=True)
    (cwd / path).write_text(block.text)


@dataclass
class DocumentRun:
    """What running documents left: every block (with the outputs of what ran), the python
    namespaces by (document, heading), the working directory and the first failure, if any."""

    blocks: list[Block]
    namespaces: dict[tuple[str, str], dict]
    cwd: Path
    failure: Exception | None


def run_documents(documents: list[Path], cwd: Path) -> DocumentRun:
    """Every block of ``documents``, run or checked in order in ``cwd``; stops at the first failure."""
    blocks = [block for path in documents for block in markdown_blocks(path.read_text(), str(path.relative_to(ROOT)))]
    namespaces: dict[tuple[str, str], dict] = {}
    failure = None
    old_cwd, old_path = os.getcwd(), list(sys.path)
    os.chdir(cwd)
    sys.path.insert(0, str(cwd))
    try:
        for block in blocks:
            if block.tag.startswith("{"):
                continue
            assert block.tag in KNOWN_TAGS, f"{block.where}: unknown block type {block.tag!r}"
            if block.text.startswith(FILE_MARK):
                write_file_block(block, cwd)
            elif block.tag in SHELL_TAGS:
                run_shell_block(block, cwd)
            elif block.tag == "python":
                # run as a script runs them, so that a snippet's `if __name__ == "__main__":` block runs
                namespace = namespaces.setdefault((block.document, block.heading), {"__name__": "__main__"})
                with contextlib.redirect_stdout(io.StringIO()) as out:
                    exec(compile(block.text, block.where, "exec"), namespace)
                block.outputs["python"] = out.getvalue()
            elif block.tag == "yaml":
                check_yaml(block)
            else:
                check_text(block)
    except Exception as err:  # the failing block's message is the report of the test that runs them
        failure = err
    finally:
        os.chdir(old_cwd)
        sys.path[:] = old_path
    return DocumentRun(blocks, namespaces, cwd, failure)


def states_the_long_convention(run: DocumentRun, runner: str) -> None:
    """Within a screen of the first command marked long, its document says what the mark means
    and names the test that runs the rest."""
    first_long = next(b for b in run.blocks if b.tag in SHELL_TAGS and LONG_MARK in b.text)
    text = (ROOT / first_long.document).read_text().splitlines()
    nearby = "\n".join(text[max(0, first_long.line - 15) : first_long.end + 15])
    assert f"`{LONG_MARK}" in nearby and runner in nearby, (
        f"{first_long.where}: the first long command is not explained near it (mentioning {runner})"
    )


def snippets_write_what_they_say(run: DocumentRun) -> list[tuple[str, str]]:
    """Each snippet's `# writes PATH` comment names a file it left behind; the (where, path) promised."""
    assert run.failure is None, "an earlier block failed"
    promised = [
        (b.where, path) for b in run.blocks if b.tag == "python" for path in re.findall(r"# writes (\S+)", b.text)
    ]
    for where, path in promised:
        assert (run.cwd / path).is_file(), f"{where}: the snippet says it writes {path}, which does not exist"
    return promised


def snippet_figures(run: DocumentRun) -> int:
    """A snippet that prints a table states a figure of it as `# <column>: <value>`; the number stated."""
    assert run.failure is None, "an earlier block failed"
    stated = [
        (b, m)
        for b in run.blocks
        if b.tag == "python" and not b.text.startswith(FILE_MARK)
        for m in re.finditer(r"# ([^#\n]+): (\S+)$", b.text, re.M)
    ]
    for block, match in stated:
        (row,) = markdown_tables(block.outputs["python"])[0]
        column, figure = match.groups()
        assert same_figure(figure, row[column]), (
            f"{block.where}: the snippet says {column} {figure}, it prints {row[column]}"
        )
    return len(stated)


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


def same_figure(shown: str, printed: str) -> bool:
    """Equal text, and numbers equal to within one unit of the shown figure's last printed digit
    (another CPU may round a seeded episode's last digit the other way)."""
    if NUMBER.sub("#", shown) != NUMBER.sub("#", printed):
        return False
    for a, b in zip(NUMBER.findall(shown), NUMBER.findall(printed)):
        x, y = float(a), float(b)
        if abs(x) < ROUNDING_LEVEL and abs(y) < ROUNDING_LEVEL:
            continue
        mantissa = a.split("e")[0]
        decimals = len(mantissa.split(".")[1]) if "." in mantissa else 0
        exponent = int(a.split("e")[1]) if "e" in a else 0
        if not math.isclose(x, y, abs_tol=1.01 * 10.0 ** (exponent - decimals)):
            return False
    return True


def compare_table(shown_rows, printed_rows, keys, where):
    index = {tuple(row[k] for k in keys): row for row in printed_rows}
    assert len(shown_rows) == len(index), f"{where}: {len(shown_rows)} rows, the command prints {len(index)}"
    for row in shown_rows:
        key = tuple(row[k] for k in keys)
        assert key in index, f"{where}: the command prints no row {key}"
        for column, cell in row.items():
            assert column in index[key], f"{where}: the command prints no column {column!r}"
            same = cell == index[key][column] if column in EXACT_COLUMNS else same_figure(cell, index[key][column])
            assert same, f"{where}: {key}, {column}: shown {cell}, the command prints {index[key][column]}"


def aligned_tables(text: str) -> list[list[dict[str, str]]]:
    """The plain-text tables of ``text`` that a terminal shows (a heading line, then rows, columns
    apart by two or more spaces, a blank line after), each a list of rows {heading: cell}."""
    tables, rows = [], []
    for line in text.splitlines() + [""]:
        cells = re.split(r"\s{2,}", line.strip()) if line.strip() and not line.startswith("|") else []
        cells = cells if len(cells) >= 2 else []  # a line of prose is no row
        if cells and (not rows or len(cells) == len(rows[0])):
            rows.append(cells)
            continue
        if len(rows) >= 2:  # a line of another shape ends the table
            tables.append([dict(zip(rows[0], row)) for row in rows[1:]])
        rows = [cells] if cells else []
    return tables


def block_and_text_table(run: DocumentRun, command_start: str) -> tuple[Block, list[dict[str, str]]]:
    """The first block with a command that starts with ``command_start`` and, in the next
    ``text`` block of its document, the aligned table it shows; and that table."""
    assert run.failure is None, "an earlier block failed"
    for index, block in enumerate(run.blocks):
        if block.tag in SHELL_TAGS and any(c.startswith(command_start) for c, _ in shell_commands(block)):
            shown = next((b for b in run.blocks[index + 1 :] if b.tag == "text" and b.document == block.document), None)
            tables = aligned_tables(shown.text) if shown is not None else []
            if tables:
                return block, tables[0]
    raise AssertionError(f"no block runs {command_start!r} with a text block of a table after it")


def block_and_table(run: DocumentRun, command_start: str) -> tuple[Block, list[dict[str, str]]]:
    """The first block with a command that starts with ``command_start`` and a table after it,
    before the next block of its document; and that table."""
    assert run.failure is None, "an earlier block failed"
    for block in run.blocks:
        if block.tag in SHELL_TAGS and any(c.startswith(command_start) for c, _ in shell_commands(block)):
            after = "\n".join((ROOT / block.document).read_text().splitlines()[block.end :])
            tables = markdown_tables(after.split("\n```")[0])
            if tables:
                return block, tables[0]
    raise AssertionError(f"no block runs {command_start!r} with a table after it")
