"""The hardened reader of config files: every file comes from someone else, so each step is bounded.

A config file is a regular file named *.yaml or *.yml of at most :data:`MAX_CONFIG_BYTES` (FIFOs,
devices and directories are refused before they are read, by
:func:`stewart_env.files.read_regular`), UTF-8 text, read with YAML's safe loader, nesting at most
32 levels deep and holding at most 5000 values once aliases are expanded; a key given twice in
one mapping is an error (a merge, <<: *anchor, may still be overridden). Every problem is a
:class:`~stewart_env.params.ConfigError` naming the file, and its message quotes no line
of the file.
"""

from __future__ import annotations

from pathlib import Path

import yaml

from stewart_env.files import DocumentError, FileError, YAMLNestedTooDeep, load_yaml, read_regular
from stewart_env.params.checks import ConfigError, key_names

__all__ = ["CONFIG_SUFFIXES", "MAX_CONFIG_BYTES", "read_config_text", "parse_config"]

#: Largest platform config file accepted, bytes. The shipped configs are about 4 KB.
MAX_CONFIG_BYTES = 1 << 20
#: The suffixes of a config file's name.
CONFIG_SUFFIXES = (".yaml", ".yml")
# A config has about 200 values nested 4 deep; far larger documents are refused before they are
# built (a few KB of nested YAML aliases can expand to billions of values).
_MAX_YAML_DEPTH = 32
_MAX_YAML_VALUES = 5_000
# Longest integer literal read; Python's int() takes quadratic time in the literal's length.
_MAX_INT_LITERAL = 1000


def read_config_text(path: Path) -> str:
    """The text of a config file, after checking that it is a regular *.yaml/*.yml file of at
    most MAX_CONFIG_BYTES (:func:`stewart_env.files.read_regular`: FIFOs, devices and
    directories are refused before they are read).

    Args:
        path: the config file.

    Raises:
        ConfigError: a file of another suffix, kind or size, unreadable or not UTF-8 (naming it).
    """
    source = str(path)
    if path.suffix.lower() not in CONFIG_SUFFIXES:
        raise ConfigError("", "not a platform config: the file name must end in .yaml or .yml", source)
    try:
        data = read_regular(path, MAX_CONFIG_BYTES, "config file")
    except FileError as err:
        raise ConfigError("", err.problem, source) from None
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as err:
        raise ConfigError("", f"not UTF-8 text (invalid byte at offset {err.start})", source) from None


def parse_config(text: str, source: str) -> object:
    """The document of a config file's `text` (read from `source`), by the bounded loader.

    Args:
        text: the file's text.
        source: where it was read from, for the errors.

    Raises:
        ConfigError: text that is no YAML, or beyond the loader's bounds.
    """
    try:
        return load_yaml(text, _ConfigLoader)
    except DocumentError as err:
        raise ConfigError("", err.problem, source) from None


class _ConfigLoader(yaml.SafeLoader):
    """YAML's safe loader, bounded: nesting depth, the number of values after alias expansion
    (a "billion laughs" document of nested aliases is refused before it is built) and the length
    of integer literals; duplicate keys are refused."""

    def __init__(self, stream: str):
        super().__init__(stream)
        self._depth = 0
        self._nodes = 0

    def compose_node(self, parent, index):
        # The composer recurses once per level: bound it before Python's recursion limit. Counting
        # nodes stops a long document early (PyYAML parses about 100 KB/s).
        self._depth += 1
        self._nodes += 1
        try:
            if self._depth > _MAX_YAML_DEPTH:
                raise YAMLNestedTooDeep(_MAX_YAML_DEPTH, self.peek_event().start_mark)
            if self._nodes > _MAX_YAML_VALUES:
                raise yaml.composer.ComposerError(
                    None, None, f"more than {_MAX_YAML_VALUES} values", self.peek_event().start_mark
                )
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1

    def construct_document(self, node):
        _check_expansion(node)
        return super().construct_document(node)

    def construct_mapping(self, node, deep=False):
        # PyYAML keeps the last of two equal keys: one of two values would be dropped unseen.
        # Keys brought in by a merge (<<: *anchor) may be overridden, as YAML intends.
        if isinstance(node, yaml.MappingNode):
            seen = set()
            for key_node, _ in node.value:
                if isinstance(key_node, yaml.ScalarNode) and key_node.tag != "tag:yaml.org,2002:merge":
                    if (key_node.tag, key_node.value) in seen:
                        raise yaml.constructor.ConstructorError(
                            "while constructing a mapping",
                            node.start_mark,
                            f"duplicate key {key_names([key_node.value])}",
                            key_node.start_mark,
                        )
                    seen.add((key_node.tag, key_node.value))
        return super().construct_mapping(node, deep)

    def construct_yaml_int(self, node):
        if len(node.value) > _MAX_INT_LITERAL:
            raise yaml.constructor.ConstructorError(
                None, None, f"an integer literal of {len(node.value)} characters", node.start_mark
            )
        return super().construct_yaml_int(node)


_ConfigLoader.add_constructor("tag:yaml.org,2002:int", _ConfigLoader.construct_yaml_int)


def _children(node: yaml.Node) -> list[yaml.Node]:
    if isinstance(node, yaml.SequenceNode):
        return node.value
    if isinstance(node, yaml.MappingNode):
        return [child for pair in node.value for child in pair]
    return []


def _check_expansion(root: yaml.Node) -> None:
    """Refuse a document that, once its aliases are expanded (an alias repeats its anchor's node
    object), holds more than _MAX_YAML_VALUES values, nests deeper than _MAX_YAML_DEPTH or
    contains itself. Iterative: a chain of aliases can be far deeper than the recursion limit."""
    sizes: dict[int, int] = {}
    depths: dict[int, int] = {}
    started: set[int] = set()
    stack = [(root, False)]
    while stack:
        node, children_done = stack.pop()
        key = id(node)
        if not children_done:
            if key in sizes:
                continue
            if key in started:  # reached again from inside its own expansion
                raise yaml.constructor.ConstructorError(
                    None, None, "an alias refers to its own anchor", node.start_mark
                )
            started.add(key)
            stack.append((node, True))
            stack.extend((child, False) for child in _children(node))
            continue
        children = _children(node)
        sizes[key] = 1 + sum(sizes[id(child)] for child in children)
        depths[key] = 1 + max((depths[id(child)] for child in children), default=0)
        started.discard(key)
        if sizes[key] > _MAX_YAML_VALUES:
            raise yaml.constructor.ConstructorError(
                None, None, f"more than {_MAX_YAML_VALUES} values (after expanding aliases)", node.start_mark
            )
        if depths[key] > _MAX_YAML_DEPTH:
            deep = YAMLNestedTooDeep(_MAX_YAML_DEPTH, node.start_mark)
            deep.problem += " (after expanding aliases)"
            raise deep
