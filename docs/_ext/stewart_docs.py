"""stewart-env's own Sphinx extension: the pages that are generated from the code at build time.

A page's source may hold, on a line of its own, one of these markers; before the page is parsed
the marker is replaced by Markdown made from the code (Sphinx's ``source-read`` event), so the
site never carries a hand-kept copy of what the code says:

- ``<!-- generated: env card -->``: the environment card, the class docstring of
  :class:`stewart_env.envs.StewartPlatformEnv` (Gymnasium's Markdown card format);
- ``<!-- generated: command line -->``: every ``stewart-env`` verb's usage and help, from the
  argparse parser that :func:`stewart_env.cli.build_parser` builds.

The environment page's picture, frames of one seeded episode drawn by the environment's own
renderer, is drawn at build time too (:func:`episode_figure`).
"""

from __future__ import annotations

import argparse
import inspect
import os
import re
from pathlib import Path

ENV_CARD = "<!-- generated: env card -->"
COMMAND_LINE = "<!-- generated: command line -->"
EPISODE_FIGURE = Path("_generated") / "episode.png"
# argparse wraps its help to the terminal's width; the site's code blocks show about this many columns
HELP_COLUMNS = 90


def env_card(heading_level: int = 2) -> str:
    """The env card, the class docstring of StewartPlatformEnv, its ``##`` headings moved to
    ``heading_level``."""
    from stewart_env.envs import StewartPlatformEnv

    shift = heading_level - 2
    lines = []
    for line in inspect.cleandoc(StewartPlatformEnv.__doc__).splitlines():
        if line.startswith("#"):
            hashes = len(line) - len(line.lstrip("#"))
            line = "#" * (hashes + shift) + line[hashes:]
        lines.append(line)
    return "\n".join(lines)


def _subcommands(parser: argparse.ArgumentParser) -> list[tuple[str, str, argparse.ArgumentParser]]:
    """(verb, one-line help, parser) of each subcommand, in the order of the top-level help."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            helps = {a.dest: a.help or "" for a in action._choices_actions}
            return [(verb, helps.get(verb, ""), sub) for verb, sub in action.choices.items()]
    return []


def command_line() -> str:
    """Markdown: the top-level usage, then one section per verb with its usage and help."""
    from stewart_env.cli import build_parser

    old = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = str(HELP_COLUMNS)
    try:
        parser = build_parser()
        parts = ["```text", parser.format_help().rstrip(), "```", ""]
        for verb, summary, sub in _subcommands(parser):
            parts += [f"## `stewart-env {verb}`", "", summary[:1].upper() + summary[1:] + ".", ""]
            parts += ["```text", sub.format_help().rstrip(), "```", ""]
    finally:
        if old is None:
            del os.environ["COLUMNS"]
        else:
            os.environ["COLUMNS"] = old
    return "\n".join(parts)


def episode_figure(path: Path, seed: int = 0, steps: tuple[int, ...] = (0, 10, 30, 100)) -> Path:
    """Frames of one seeded set-point episode under the PD baseline with gravity compensation,
    two a row, drawn by the environment's renderer (``render_mode="rgb_array"``)."""
    import gymnasium as gym
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from stewart_env.agents import PDPolicy

    env = gym.make("StewartPlatform-v1", render_mode="rgb_array", width=480, height=480)
    policy = PDPolicy(env, gravity_compensation=True)
    obs, _ = env.reset(seed=seed)
    frames = {}
    for step in range(max(steps) + 1):
        if step in steps:
            frames[step] = env.render()
        action, _ = policy.predict(obs)
        obs, *_ = env.step(action)
    env.close()
    # each frame carries its own time stamp and force colour bar
    rows = (len(steps) + 1) // 2
    fig, axes = plt.subplots(rows, 2, figsize=(9.6, 4.8 * rows), squeeze=False)
    for ax in axes.flat:
        ax.axis("off")
    for ax, step in zip(axes.flat, steps):
        ax.imshow(frames[step])
    fig.subplots_adjust(left=0, right=1, bottom=0, top=1, wspace=0.02, hspace=0.02)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def _generate(app, docname: str, source: list[str]) -> None:
    text = source[0]
    if ENV_CARD in text:
        text = text.replace(ENV_CARD, env_card())
    if COMMAND_LINE in text:
        text = text.replace(COMMAND_LINE, command_line())
    source[0] = text


def _draw_figures(app) -> None:
    episode_figure(Path(app.srcdir) / EPISODE_FIGURE)


def _import(dotted: str):
    """The object a dotted name names, or None."""
    import importlib

    parts = dotted.split(".")
    for split in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:split]))
        except ImportError:
            continue
        try:
            for attr in parts[split:]:
                obj = getattr(obj, attr)
        except AttributeError:
            return None
        return obj
    return None


def _same_object(app, env, node, contnode):
    """A reference by another of an object's names (``stewart_env.rollout`` for
    ``stewart_env.integrate.rollout``) resolves to where the site documents that object."""
    if node.get("refdomain") != "py":
        return None
    obj = _import(node["reftarget"])
    if obj is None or not hasattr(obj, "__qualname__"):
        return None
    domain = env.get_domain("py")
    for name in domain.objects:
        if name.rsplit(".", 1)[-1] == obj.__qualname__.rsplit(".", 1)[-1] and _import(name) is obj:
            return domain.resolve_xref(env, node["refdoc"], app.builder, node["reftype"], name, node, contnode)
    return None


def setup(app):
    app.connect("missing-reference", _same_object)
    app.connect("builder-inited", _draw_figures)
    app.connect("source-read", _generate)
    # after napoleon (priority 500) has turned the Google sections into reStructuredText
    app.connect("autodoc-process-docstring", _docstring, priority=600)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}


# -- docstrings in the API reference ------------------------------------------------------------

def _rst_problems(lines: list[str], env) -> list[str]:
    """The docutils warnings and errors of reStructuredText ``lines``, Sphinx's own roles and
    directives (which plain docutils does not know) aside."""
    import io

    from docutils.core import publish_doctree
    from docutils.utils import Reporter

    stream = io.StringIO()
    publish_doctree("\n".join(lines), settings_overrides={
        "report_level": Reporter.WARNING_LEVEL, "halt_level": Reporter.SEVERE_LEVEL + 1,
        "warning_stream": stream, "file_insertion_enabled": False, "raw_enabled": False, "env": env})
    problems = []
    for message in stream.getvalue().split("<string>:")[1:]:
        if "Unknown interpreted text role" in message or "Unknown directive type" in message \
                or 'No role entry for' in message or 'No directive entry for' in message \
                or "Trying" in message and "as canonical" in message:
            continue
        problems.append(message.strip().splitlines()[0])
    return problems


# inline literals and roles, left as they are when plain text is escaped
_MARKUP = re.compile(r"(``.+?``|:[\w:.-]+:`[^`]+`)")


def _indent(line: str) -> int:
    return len(line) - len(line.lstrip())


def _escaped(line: str) -> str:
    """``|`` and ``*`` outside inline literals and roles escaped: norms and products, not
    substitutions and emphasis."""
    parts = _MARKUP.split(line)
    return "".join(part if i % 2 else part.replace("|", r"\|").replace("*", r"\*") for i, part in enumerate(parts))


def _plain_text_repaired(lines: list[str]) -> list[str]:
    """Plain text made reStructuredText.  An indented block under a line ending in a colon
    ("Options:" and its entries) becomes a bullet list, one item per line at the block's
    indentation, deeper lines joined to their item, and one set off by a blank line a literal
    block, kept as written; elsewhere a blank line goes wherever the
    indentation changes; ``|`` and ``*`` are escaped."""
    out, i = [], 0
    while i < len(lines):
        line = lines[i]
        following = lines[i + 1] if i + 1 < len(lines) else ""
        if line.rstrip().endswith(":") and following.strip() and _indent(following) > _indent(line):
            out += [_escaped(line), ""]
            base, items, i = _indent(following), [], i + 1
            while i < len(lines) and lines[i].strip() and _indent(lines[i]) >= base:
                if _indent(lines[i]) == base:
                    items.append(lines[i].strip())
                else:
                    items[-1] += " " + lines[i].strip()
                i += 1
            out += [" " * _indent(line) + "- " + _escaped(item) for item in items] + [""]
            continue
        after = next((later for later in lines[i + 1:] if later.strip()), "")
        if line.rstrip().endswith(":") and not line.rstrip().endswith("::") and not following.strip() \
                and _indent(after) > _indent(line):
            out.append(_escaped(line) + ":")  # a block set off by a blank line: a listing, kept as written
            out += lines[i + 1:i + 2]
            i += 2
            while i < len(lines) and (not lines[i].strip() or _indent(lines[i]) > _indent(line)):
                out.append(lines[i])
                i += 1
            continue
        if line.strip() and out and out[-1].strip() and _indent(line) != _indent(out[-1]):
            out.append("")
        out.append(_escaped(line) if line.strip() else line)
        i += 1
    return out


def _docstring(app, what, name, obj, options, lines: list[str]) -> None:
    """The environment card is a page of its own; a docstring written as plain text (``|x|``
    norms, ``a * b`` products, indented lists under a colon) is repaired into reStructuredText,
    or, where that is not enough, shown as written."""
    if name.endswith(".StewartPlatformEnv") and what == "class":
        lines[:] = ["The Gymnasium environment ``StewartPlatform-v1``; its card (spaces, rewards, starting state,",
                    "episode end, arguments) is the page :doc:`/environment`."]
        return
    own = inspect.getdoc(obj) or ""
    if what in ("data", "attribute") and not callable(obj) and own and lines and lines[0].strip() == own.splitlines()[0].strip():
        lines[:] = []  # a constant without a doc comment of its own: not its type's docstring (numpy's)
        return
    if not lines or not _rst_problems(lines, app.env):
        return
    repaired = _plain_text_repaired(lines)
    if not _rst_problems(repaired, app.env):
        lines[:] = repaired
    else:
        lines[:] = [".. code-block:: text", "   :class: docstring-text", ""] + ["   " + line for line in lines] + [""]
