"""YAML loading that remembers the line of every key and list item, for errors that name ``file:line``.

:func:`load_marked_yaml` returns ordinary Python values, except that mappings are :class:`MarkedDict`
and sequences :class:`MarkedList`, which carry the 1-based line of the mapping or sequence itself,
of each key, of each value and of each list item. Scalars are the usual safe-YAML types (``str``,
``int``, ``float``, ``bool``, ``None``, ...). Duplicate keys, which plain PyYAML silently collapses to
the last one, are an error here.

Convention: all line numbers are 1-based, as editors show them (PyYAML marks are 0-based).
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

__all__ = ["MarkedDict", "MarkedList", "YamlSyntaxError", "load_marked_yaml"]


class YamlSyntaxError(ValueError):
    """A file is not valid YAML (or has a duplicate key); ``line`` is 1-based or ``None``."""

    def __init__(self, message: str, line: int | None):
        super().__init__(message)
        self.line = line


class MarkedDict(dict):
    """A ``dict`` from YAML with ``line`` (of the mapping), ``key_lines`` and ``value_lines`` (per key)."""

    line: int = 0

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.key_lines: dict = {}
        self.value_lines: dict = {}

    def key_line(self, key) -> int:
        """Line of ``key`` (the mapping's own line for a key it does not have)."""
        return self.key_lines.get(key, self.line)

    def value_line(self, key) -> int:
        """Line where the value of ``key`` starts (the mapping's own line for a key it does not have)."""
        return self.value_lines.get(key, self.line)


class MarkedList(list):
    """A ``list`` from YAML with ``line`` (of the sequence) and ``item_lines`` (one per item)."""

    line: int = 0

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.item_lines: list[int] = []

    def item_line(self, index: int) -> int:
        """Line of item ``index`` (the sequence's own line when unknown)."""
        return self.item_lines[index] if 0 <= index < len(self.item_lines) else self.line


class _MarkedLoader(yaml.SafeLoader):
    """A safe loader whose mappings and sequences remember their lines."""


def _line(node: yaml.Node) -> int:
    return node.start_mark.line + 1


def _construct_mapping(loader: _MarkedLoader, node: yaml.MappingNode) -> MarkedDict:
    loader.flatten_mapping(node)  # resolves YAML merge keys (<<)
    data = MarkedDict()
    data.line = _line(node)
    for key_node, value_node in node.value:
        key = loader.construct_object(key_node, deep=True)
        try:
            hash(key)
        except TypeError:
            raise yaml.constructor.ConstructorError(None, None, "a mapping key must be a plain value",
                                                    key_node.start_mark) from None
        if key in data:
            raise yaml.constructor.ConstructorError(
                None, None, f"duplicate key {key!r} (first at line {data.key_lines[key]})", key_node.start_mark)
        data[key] = loader.construct_object(value_node, deep=True)
        data.key_lines[key] = _line(key_node)
        data.value_lines[key] = _line(value_node)
    return data


def _construct_sequence(loader: _MarkedLoader, node: yaml.SequenceNode) -> MarkedList:
    data = MarkedList(loader.construct_object(child, deep=True) for child in node.value)
    data.line = _line(node)
    data.item_lines = [_line(child) for child in node.value]
    return data


_MarkedLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_mapping)
_MarkedLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_SEQUENCE_TAG, _construct_sequence)


def load_marked_yaml(path: str | Path):
    """Load one YAML document from ``path`` with line numbers on its mappings and sequences.

    Parameters
    ----------
    path : str or Path
        A UTF-8 YAML file.

    Returns
    -------
    object
        The document: :class:`MarkedDict` / :class:`MarkedList` / scalars; ``None`` for an empty file.

    Raises
    ------
    YamlSyntaxError
        The text is not valid YAML, holds more than one document, or repeats a key in a mapping;
        ``line`` is where the parser noticed it.
    OSError
        The file cannot be read.
    """
    text = Path(path).read_text(encoding="utf-8")
    try:
        return yaml.load(text, Loader=_MarkedLoader)  # safe: _MarkedLoader is a SafeLoader subclass
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        problem = exc.problem or "invalid YAML"
        if exc.context and exc.context not in problem:
            problem = f"{exc.context}: {problem}"
        raise YamlSyntaxError(f"YAML syntax error: {problem}", None if mark is None else mark.line + 1) from None
    except yaml.YAMLError as exc:
        raise YamlSyntaxError(f"YAML syntax error: {exc}", None) from None
