"""Reading the values of a launch entry: keys checked, text substituted, booleans, seconds, conditions.

Every check that fails raises :class:`EntryFailure` with the line of the value; the loader records it as a
:class:`~.launch_plan.LaunchProblem` and goes on with the next entry.
"""

from __future__ import annotations

import difflib
import os
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType

from .launch_plan import LaunchArgument
from .marked_yaml import MarkedDict, MarkedList
from .substitutions import SubstitutionContext, SubstitutionError, substitute

__all__ = ["ENTITY_KEYS", "OLD_KEYS", "EntryFailure", "FileScope", "ValueReader", "suggest", "type_name"]

#: Keys each entity accepts; the first group of each tuple pair is required. ROS 2 spells the namespace entity
#: both ways (launch_ros exposes ``push_ros_namespace`` and ``push-ros-namespace``).
ENTITY_KEYS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "arg": (("name",), ("default", "description", "choice")),
    "let": (("name", "value"), ("if", "unless")),
    "include": (("file",), ("arg", "if", "unless")),
    "group": (("children",), ("if", "unless")),
    "push_ros_namespace": (("namespace",), ("if", "unless")),
    "push-ros-namespace": (("namespace",), ("if", "unless")),
    "node": (("exec",), ("pkg", "name", "namespace", "args", "param", "remap", "env", "respawn",
                         "respawn_delay", "respawn_max_delay", "on_exit", "output", "if", "unless")),
}
#: Keys of the project's own launch dialect before it followed ROS 2, and what ROS 2 writes instead.
OLD_KEYS: dict[tuple[str, str], str] = {
    ("node", "module"): "'pkg' and 'exec' (pkg: dptpu, exec: NODE runs dptpu.nodes.NODE)",
    ("node", "executable"): "'exec' (a program without 'pkg')",
    ("node", "required"): "'on_exit: shutdown'",
    ("arg", "choices"): "'choice', a list of {value: ...} (choice: [{value: a}, {value: b}])",
    ("group", "namespace"): "a '- push_ros_namespace: {namespace: NS}' entry among the group's children",
}
_NAMESPACE = re.compile(r"/|(/[A-Za-z_][A-Za-z0-9_]*)+")
_TRUE, _FALSE = ("true", "1"), ("false", "0")


class EntryFailure(Exception):
    """Abandon the current entry: a problem at ``line`` of the file being read."""

    def __init__(self, line: int | None, message: str):
        super().__init__(message)
        self.line, self.message = line, message


@dataclass
class FileScope:
    """One file being read."""

    path: str                       # absolute
    display: str                    # as shown in messages
    given: dict[str, str]           # argument values passed in (command line or include)
    given_from: str                 # "the command line" or "the include at main.yaml:7"
    declared: dict[str, int] = field(default_factory=dict)      # arg name -> line
    arguments: list[LaunchArgument] = field(default_factory=list)
    values: dict[str, str] = field(default_factory=dict)        # declared arg values

    @property
    def directory(self) -> str:
        return os.path.dirname(self.path)


def suggest(word: str, candidates: Sequence[str]) -> str:
    close = difflib.get_close_matches(word, list(candidates), n=1, cutoff=0.6)
    return f" (did you mean '{close[0]}'?)" if close else ""


def type_name(value) -> str:
    if value is None:
        return "nothing (null)"
    if isinstance(value, dict):
        return "a mapping"
    if isinstance(value, list):
        return "a list"
    return f"{type(value).__name__} {value!r}"


class ValueReader:
    """Typed values of an entry's keys, with ``$(...)`` substitutions done against ``environ``."""

    def __init__(self, environ: Mapping[str, str]):
        self.environ = environ

    def check_keys(self, kind: str, body: MarkedDict, required: Sequence[str] | None = None,
                   allowed: Sequence[str] | None = None) -> None:
        if required is None:
            required, optional = ENTITY_KEYS[kind]
            allowed = (*required, *optional)
        elif allowed is None:
            raise ValueError("check_keys: allowed must be given with required")
        for key in body:
            if key not in allowed and (kind, key) in OLD_KEYS:
                raise EntryFailure(body.key_line(key), f"{kind}: {key!r} is the old spelling; ROS 2 launch YAML "
                                                       f"writes {OLD_KEYS[kind, key]}")
            if key not in allowed:
                hint = suggest(str(key), allowed)
                listing = "" if hint else f" (allowed: {', '.join(allowed)})"
                raise EntryFailure(body.key_line(key), f"{kind}: unknown key {key!r}{hint}{listing}")
        for key in required:
            if key not in body:
                raise EntryFailure(body.line, f"{kind}: missing required key {key!r}")

    def context(self, scope: FileScope, variables: Mapping[str, str]) -> SubstitutionContext:
        return SubstitutionContext(variables=variables, launch_file_dir=scope.directory, environ=self.environ)

    def substitute(self, scope: FileScope, text: str, variables: Mapping[str, str], line: int, where: str) -> str:
        try:
            return substitute(text, self.context(scope, variables))
        except SubstitutionError as exc:
            raise EntryFailure(line, f"{where}: {exc}") from None

    def text(self, scope: FileScope, body: MarkedDict, key: str, kind: str, *,
             variables: Mapping[str, str] = MappingProxyType({}), substitute_values: bool = True) -> str:
        """The value of ``key`` as text: strings substituted; numbers and booleans written as YAML would."""
        value, line = body[key], body.value_line(key)
        if isinstance(value, bool):
            return "true" if value else "false"
        if isinstance(value, int | float):
            return str(value)
        if not isinstance(value, str):
            raise EntryFailure(line, f"{kind}: {key} must be text; got {type_name(value)}")
        if not substitute_values:
            return value
        return self.substitute(scope, value, dict(variables), line, f"{kind} {key}")

    def boolean(self, scope: FileScope, body: MarkedDict, key: str, kind: str, variables, default: bool) -> bool:
        if key not in body:
            return default
        value, line = body[key], body.value_line(key)
        if isinstance(value, bool):
            return value
        if isinstance(value, str):
            text = self.substitute(scope, value, variables, line, f"{kind} {key}").strip().lower()
            if text in _TRUE:
                return True
            if text in _FALSE:
                return False
            raise EntryFailure(line, f"{kind}: {key} must be true or false (or 1 / 0); got {text!r}")
        raise EntryFailure(line, f"{kind}: {key} must be true or false; got {type_name(value)}")

    def seconds(self, scope: FileScope, body: MarkedDict, key: str, kind: str, variables, default: float) -> float:
        if key not in body:
            return default
        value, line = body[key], body.value_line(key)
        if isinstance(value, str):
            text = self.substitute(scope, value, variables, line, f"{kind} {key}")
            try:
                value = float(text)
            except ValueError:
                raise EntryFailure(line, f"{kind}: {key} must be a number of seconds; got {text!r}") from None
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise EntryFailure(line, f"{kind}: {key} must be a number of seconds; got {type_name(value)}")
        if not 0 <= value < float("inf"):
            raise EntryFailure(line, f"{kind}: {key} must be a finite number of seconds >= 0; got {value}")
        return float(value)

    def condition(self, scope: FileScope, body: MarkedDict, variables, kind: str) -> bool:
        if "if" in body and "unless" in body:
            raise EntryFailure(body.key_line("unless"), f"{kind}: use either 'if' or 'unless', not both")
        if "if" in body:
            return self.boolean(scope, body, "if", kind, variables, True)
        if "unless" in body:
            return not self.boolean(scope, body, "unless", kind, variables, False)
        return True

    def choices(self, scope: FileScope, body: MarkedDict) -> tuple[str, ...] | None:
        """The values of an ``arg``'s ``choice`` list (ROS 2: ``choice: [{value: a}, {value: b}]``)."""
        if "choice" not in body:
            return None
        value = body["choice"]
        usage = "choice must be a non-empty list of {value: ...} (choice: [{value: a}, {value: b}])"
        if not isinstance(value, MarkedList) or not value:
            raise EntryFailure(body.value_line("choice"), f"arg: {usage}; got {type_name(value)}")
        found = []
        for index, item in enumerate(value):
            if not isinstance(item, MarkedDict) or list(item) != ["value"] or isinstance(item["value"], list | dict) \
                    or item["value"] is None:
                raise EntryFailure(value.item_line(index), f"arg: {usage}; got {type_name(item)}")
            entry = item["value"]
            found.append(("true" if entry else "false") if isinstance(entry, bool) else str(entry))
        return tuple(found)

    def list_of_mappings(self, body: MarkedDict, key: str, kind: str) -> MarkedList:
        value = body[key]
        if value is None:
            return MarkedList()
        if not isinstance(value, MarkedList):
            raise EntryFailure(body.value_line(key),
                               f"{kind}: {key} must be a list of mappings; got {type_name(value)}")
        for index, item in enumerate(value):
            if not isinstance(item, MarkedDict):
                raise EntryFailure(value.item_line(index), f"{kind} {key}: each item must be a mapping; "
                                                           f"got {type_name(item)}")
        return value

    def join_namespace(self, scope: FileScope, body: MarkedDict, namespace: str, variables, kind: str) -> str:
        """The namespace in effect inside ``body``: its own (absolute, or relative to ``namespace``)."""
        if "namespace" not in body:
            return namespace
        text = self.text(scope, body, "namespace", kind, variables=variables).strip()
        if not text:
            return namespace
        joined = text if text.startswith("/") else f"{namespace.rstrip('/')}/{text}"
        joined = joined.rstrip("/") or "/"
        if not _NAMESPACE.fullmatch(joined):
            raise EntryFailure(body.value_line("namespace"),
                               f"{kind}: namespace {joined!r} is not valid: components are "
                               f"letters, digits and _, not starting with a digit, "
                               f"separated by /")
        return joined
