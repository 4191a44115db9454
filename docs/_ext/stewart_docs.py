"""stewart-env's own Sphinx extension: the pages that are generated from the code at build time.

A page's source may hold, on a line of its own, one of these markers; before the page is parsed
the marker is replaced by Markdown made from the code (Sphinx's ``source-read`` event), so the
site never carries a hand-kept copy of what the code says:

- ``<!-- generated: env card -->``: the environment card, the class docstring of
  :class:`stewart_env.envs.StewartPlatformEnv` (Gymnasium's Markdown card format);
  ``<!-- generated: env card: Description, Rewards -->`` inserts the card's sections of these
  headings, and the plain marker then the card's other sections, so that a page may put its own
  text between them;
- ``<!-- generated: env summary -->``: the box at the top of an environment page, as Gymnasium's
  pages have one: the action space, each task's observation space, the import and the ids;
- ``<!-- generated: reward symbols -->``: the reward's weights and scales, each with its symbol,
  its ``task_options`` key, its meaning (the docstring of :class:`stewart_env.tasks.RewardWeights`)
  and each task's default;
- ``<!-- generated: command line -->``: every ``stewart-env`` verb's usage and help, from the
  argparse parser that :func:`stewart_env.cli.build_parser` builds;
- ``<!-- generated: extras -->``: the optional extras of ``pyproject.toml``, each with its purpose,
  the first line of the comment above it there, and its requirements;
- ``<!-- generated: log format -->``: the drive-log schema, its header's entries, its kinds and every
  column with its unit, from :func:`stewart_env.identification.log.schema_markdown`.

The environment page's picture, frames of one seeded episode drawn by the environment's own
renderer, is drawn at build time too (:func:`episode_figure`).

MathJax is shipped with the site (``_static/mathjax/``, from the package sphinx-mathjax-offline
of the ``docs`` extra) instead of loaded from a CDN, so that the pages' maths renders offline and
from a checkout's own build (:func:`_ship_mathjax`).
"""

from __future__ import annotations

import argparse
import inspect
import os
import re
from pathlib import Path

ENV_CARD = "<!-- generated: env card -->"
# a marker of some of the card's sections, by heading
ENV_CARD_SECTIONS = re.compile(r"^<!-- generated: env card: (.+?) -->$", flags=re.M)
ENV_SUMMARY = "<!-- generated: env summary -->"
REWARD_SYMBOLS = "<!-- generated: reward symbols -->"
COMMAND_LINE = "<!-- generated: command line -->"
EXTRAS = "<!-- generated: extras -->"
LOG_FORMAT = "<!-- generated: log format -->"
PYPROJECT = Path(__file__).resolve().parents[2] / "pyproject.toml"
#: The symbol of each weight and scale of the reward (stewart_env.tasks.RewardWeights) in the
#: environment page's formula.
REWARD_SYMBOL = {
    "position_reward_weight": "w_p",
    "position_reward_scale": "s_p",
    "orientation_reward_weight": "w_o",
    "orientation_reward_scale": "s_o",
    "velocity_cost_weight": "w_v",
    "velocity_cost_scale": "s_v",
    "angular_velocity_cost_scale": r"s_\omega",
    "ctrl_cost_weight": "w_a",
    "termination_cost": "c",
}
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


def card_sections(card: str) -> list[tuple[str, str]]:
    """(heading, Markdown from the heading on) of each ``##`` section of ``card``, in order; text
    before the first heading is a section of heading ``""``."""
    sections: list[tuple[str, list[str]]] = [("", [])]
    fence = False
    for line in card.splitlines():
        if line.startswith("```"):
            fence = not fence
        if not fence and line.startswith("## "):
            sections.append((line[3:].strip(), []))
        sections[-1][1].append(line)
    return [(heading, "\n".join(lines).strip("\n")) for heading, lines in sections if "".join(lines).strip()]


def env_card_on_page(text: str, docname: str = "") -> str:
    """``text`` with its env-card markers replaced: each section marker by the sections it names,
    then the plain marker by the card's sections no section marker names.

    Raises:
        ExtensionError: a section marker names a heading the card does not have.
    """
    from sphinx.errors import ExtensionError

    sections = dict(card_sections(env_card()))
    placed: list[str] = []

    def insert(match: re.Match) -> str:
        headings = [h.strip() for h in match.group(1).split(",")]
        unknown = [h for h in headings if h not in sections]
        if unknown:
            raise ExtensionError(
                f"{docname}: the env card has no section {unknown[0]!r} "
                f"(its sections: {', '.join(h for h in sections if h)})"
            )
        placed.extend(headings)
        return "\n\n".join(sections[h] for h in headings)

    text = ENV_CARD_SECTIONS.sub(insert, text)
    if ENV_CARD in text:
        text = text.replace(ENV_CARD, "\n\n".join(s for h, s in sections.items() if h not in placed))
    return text


def env_summary() -> str:
    """Markdown: the environment's summary box (a table without a header row): its action space,
    the observation space of each task with the default arguments, the import and the ids."""
    import gymnasium as gym

    from stewart_env.registration import CURRENT_VERSION, ENV_ID, ENV_IDS
    from stewart_env.tasks import TASKS

    spaces: dict[str, list[str]] = {}
    for task in TASKS:
        env = gym.make(ENV_ID, task=task)
        action_space = str(env.action_space)
        spaces.setdefault(str(env.observation_space), []).append(f"`{task}`")
        env.close()
    observation = "; ".join(f"`{space}` for " + ", ".join(tasks) for space, tasks in spaces.items())
    earlier = ", ".join(f"`{ENV_IDS[v]}`" for v in sorted(ENV_IDS, reverse=True) if v != CURRENT_VERSION)
    rows = [
        ("Action Space", f"`{action_space}`"),
        ("Observation Space", observation + ", with the default arguments"),
        ("import", f'`import stewart_env`, then `gymnasium.make("{ENV_ID}")`'),
        ("id", f"`{ENV_ID}`; earlier versions: {earlier} ([Version History](#version-history))"),
    ]
    lines = ["```{list-table}", ":class: env-summary", ""]
    for name, value in rows:
        lines += [f"* - {name}", f"  - {value}"]
    return "\n".join(lines + ["```"])


def _attribute_docs(cls) -> dict[str, str]:
    """{name: text} of the ``Attributes:`` section of a Google-style class docstring."""
    doc = inspect.getdoc(cls) or ""
    section = doc.split("Attributes:", 1)[1] if "Attributes:" in doc else ""
    found: dict[str, str] = {}
    name = None
    for line in section.splitlines():
        if line.strip() and not line.startswith(" "):
            break  # the next section
        entry = re.match(r"^\s{4}(\w+): (.*)$", line)
        if entry:
            name, found[entry.group(1)] = entry.group(1), entry.group(2).strip()
        elif name and line.strip():
            found[name] += " " + line.strip()
    return found


def reward_symbols() -> str:
    """Markdown: a table of the reward's weights and scales, each with its symbol, its option, its
    meaning and its default in each task.

    Raises:
        ExtensionError: a field of RewardWeights without a symbol in REWARD_SYMBOL.
    """
    import dataclasses

    from sphinx.errors import ExtensionError

    import stewart_env as se
    from stewart_env.tasks import TASKS, RewardWeights, make_task

    fields = [f.name for f in dataclasses.fields(RewardWeights)]
    if set(fields) != set(REWARD_SYMBOL):
        raise ExtensionError(
            f"docs/_ext/stewart_docs.py: REWARD_SYMBOL names {sorted(REWARD_SYMBOL)}, RewardWeights has {fields}"
        )
    meanings = _attribute_docs(RewardWeights)
    params = se.load_platform("dasgupta1998")
    weights = {task: make_task(task, params, control_dt=0.01).weights for task in TASKS}
    rows = ["| symbol | option | meaning | default |", "|---|---|---|---|"]
    for name in fields:
        by_value: dict[str, list[str]] = {}
        for task, w in weights.items():
            by_value.setdefault(f"{getattr(w, name):g}", []).append(f"`{task}`")
        default = (
            next(iter(by_value))
            if len(by_value) == 1
            else "; ".join(f"{value} ({', '.join(tasks)})" for value, tasks in by_value.items())
        )
        rows.append(f"| ${REWARD_SYMBOL[name]}$ | `{name}` | {meanings.get(name, '')} | {default} |")
    return "\n".join(rows)


def extras() -> list[tuple[str, str, list[str]]]:
    """(extra, purpose, requirements) of each optional extra of ``pyproject.toml``, in its order:
    the purpose is the first line of the comment right above the extra.

    Raises:
        ExtensionError: an extra without a comment above it.
    """
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10
        import tomli as tomllib
    from sphinx.errors import ExtensionError

    text = PYPROJECT.read_text(encoding="utf-8")
    declared = tomllib.loads(text)["project"]["optional-dependencies"]
    lines = text.splitlines()
    section = lines.index("[project.optional-dependencies]")
    found = []
    for extra, requirements in declared.items():
        start = next(i for i, line in enumerate(lines) if i > section and re.match(rf"^{re.escape(extra)}\s*=", line))
        above = start
        while above > 0 and lines[above - 1].startswith("#"):
            above -= 1
        if above == start:
            raise ExtensionError(
                f"pyproject.toml: the extra {extra!r} has no comment above it (its first line "
                "is the extra's purpose on the getting-started page)"
            )
        found.append((extra, lines[above].lstrip("# ").strip(), list(requirements)))
    return found


def extras_table() -> str:
    """Markdown: the table of the optional extras (extra, what it is for, what it installs)."""
    rows = ["| extra | for | installs |", "|---|---|---|"]
    for extra, purpose, requirements in extras():
        rows.append(f"| `{extra}` | {purpose} | {', '.join(f'`{r}`' for r in requirements)} |")
    return "\n".join(rows)


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
    if ENV_CARD in text or ENV_CARD_SECTIONS.search(text):
        text = env_card_on_page(text, docname)
    if ENV_SUMMARY in text:
        text = text.replace(ENV_SUMMARY, env_summary())
    if REWARD_SYMBOLS in text:
        text = text.replace(REWARD_SYMBOLS, reward_symbols())
    if COMMAND_LINE in text:
        text = text.replace(COMMAND_LINE, command_line())
    if EXTRAS in text:
        text = text.replace(EXTRAS, extras_table())
    if LOG_FORMAT in text:
        from stewart_env.identification.log import schema_markdown

        text = text.replace(LOG_FORMAT, schema_markdown())
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


def _ship_mathjax(app) -> None:
    """Set up sphinx-mathjax-offline as part of this extension: it points ``mathjax_path`` at its
    MathJax 3 and copies MathJax into the build when the build has finished, which is safe in a
    parallel build, but the package does not say so (Sphinx would warn under ``-j``).

    Raises:
        ExtensionError: the package is not installed (it comes with the ``docs`` extra).
    """
    import importlib

    from sphinx.errors import ExtensionError

    try:
        offline = importlib.import_module("sphinx-mathjax-offline")  # the package's module name has hyphens
    except ImportError:
        raise ExtensionError(
            "the site ships MathJax from the package sphinx-mathjax-offline, which is not "
            'installed: pip install -e ".[docs]"'
        ) from None
    offline.setup(app)


def setup(app):
    """Register the extension with Sphinx: the generated pages, the figures, MathJax and the docstrings.

    Args:
        app: the Sphinx application.

    Returns:
        The extension's metadata.
    """
    app.setup_extension("sphinx.ext.mathjax")
    _ship_mathjax(app)
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
    publish_doctree(
        "\n".join(lines),
        settings_overrides={
            "report_level": Reporter.WARNING_LEVEL,
            "halt_level": Reporter.SEVERE_LEVEL + 1,
            "warning_stream": stream,
            "file_insertion_enabled": False,
            "raw_enabled": False,
            "env": env,
        },
    )
    problems = []
    for message in stream.getvalue().split("<string>:")[1:]:
        if (
            "Unknown interpreted text role" in message
            or "Unknown directive type" in message
            or "No role entry for" in message
            or "No directive entry for" in message
            or "Trying" in message
            and "as canonical" in message
        ):
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
        after = next((later for later in lines[i + 1 :] if later.strip()), "")
        if (
            line.rstrip().endswith(":")
            and not line.rstrip().endswith("::")
            and not following.strip()
            and _indent(after) > _indent(line)
        ):
            out.append(_escaped(line) + ":")  # a block set off by a blank line: a listing, kept as written
            out += lines[i + 1 : i + 2]
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
        lines[:] = [
            "The Gymnasium environment ``StewartPlatform-v1``; its card (spaces, rewards, starting state,",
            "episode end, arguments) is the page :doc:`/environment`.",
        ]
        return
    own = inspect.getdoc(obj) or ""
    if (
        what in ("data", "attribute")
        and not callable(obj)
        and own
        and lines
        and lines[0].strip() == own.splitlines()[0].strip()
    ):
        lines[:] = []  # a constant without a doc comment of its own: not its type's docstring (numpy's)
        return
    if not lines or not _rst_problems(lines, app.env):
        return
    repaired = _plain_text_repaired(lines)
    if not _rst_problems(repaired, app.env):
        lines[:] = repaired
    else:
        lines[:] = [".. code-block:: text", "   :class: docstring-text", ""] + ["   " + line for line in lines] + [""]
