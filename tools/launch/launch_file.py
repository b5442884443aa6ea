"""Launch files: parse, validate and resolve a YAML launch file into a :class:`LaunchPlan`.

The format is ROS 2's YAML front end (``docs/launch.md`` describes every key)::

    launch:
      - arg: {name: rate, default: "10", description: frames per second}
      - include: {file: camera.yaml, arg: [{name: rate, value: "$(var rate)"}]}
      - group:
          namespace: /scanner
          children:
            - node:
                module: dptpu.nodes.phase
                name: phase
                param: [{name: min_modulation, value: 5.0}, {from: params.yaml}]
                remap: [{from: /camera/image_raw, to: /sim/image}]
                respawn: true
                respawn_delay: 1.0

Everything is checked before anything starts: unknown and missing keys, types, ``$(...)``
substitutions, that modules (``python -m``), executables, included files and parameter files exist,
that node names are unique. Every problem found becomes one :class:`LaunchProblem` naming the file and
line, e.g. ``sim_rig.yaml:14: node: unknown key 'remapp' (did you mean 'remap'?)``, and all of them are
raised together as one :class:`LaunchFileError`.

Scoping: each file sees only its own ``arg`` values (from the command line for the top file, from the
``include``'s ``arg`` list for an included one, else the default) and the ``let`` values set before the
use; a ``group`` scopes the ``let`` inside it and pushes its namespace onto every node within,
included files too.
"""
from __future__ import annotations

import dataclasses
import difflib
import os
import re
import shlex
import shutil
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from .command_line import PARAMETER_SCALAR_TYPES, InlineParameter, ParameterFile, ros_arguments
from .marked_yaml import MarkedDict, MarkedList, YamlSyntaxError, load_marked_yaml
from .python_modules import module_problem
from .respawn import RespawnPolicy
from .substitutions import SubstitutionContext, SubstitutionError, has_substitution, substitute

__all__ = [
    "LaunchArgument",
    "LaunchFileError",
    "LaunchPlan",
    "LaunchProblem",
    "NodeLaunch",
    "ENTITY_KEYS",
    "OUTPUT_MODES",
    "declared_arguments",
    "load_launch_file",
    "parse_launch_arguments",
]

#: Keys each entity accepts; the first group of each tuple pair is required.
ENTITY_KEYS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "arg": (("name",), ("default", "description", "choices")),
    "let": (("name", "value"), ("if", "unless")),
    "include": (("file",), ("arg", "if", "unless")),
    "group": (("children",), ("namespace", "if", "unless")),
    "node": ((), ("module", "executable", "name", "namespace", "args", "param", "remap", "env", "respawn",
                  "respawn_delay", "respawn_max_delay", "required", "output", "if", "unless")),
}
#: Where a node's output goes: the launcher's terminal (prefixed), a log file, or both.
OUTPUT_MODES = ("screen", "log", "both")
#: Seconds: default cap of the respawn backoff (raised to ``respawn_delay`` when that is larger).
DEFAULT_RESPAWN_MAX_DELAY_S = 30.0

_MAX_PROBLEMS = 50
_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_NAMESPACE = re.compile(r"/|(/[A-Za-z_][A-Za-z0-9_]*)+")
_ARG_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_.\-]*")
_PARAM_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*")
_ENV_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_TRUE, _FALSE = ("true", "1"), ("false", "0")


# ------------------------------------------------------------------------------------------------
# results
# ------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class LaunchProblem:
    """One problem in a launch file: ``file`` as displayed, 1-based ``line`` (``None``: the whole file)."""

    file: str
    line: int | None
    message: str

    def __str__(self) -> str:
        return f"{self.file}:{self.line}: {self.message}" if self.line else f"{self.file}: {self.message}"


class LaunchFileError(ValueError):
    """A launch file (or its command-line arguments) is invalid; ``problems`` lists every problem found."""

    def __init__(self, problems: Sequence[LaunchProblem]):
        self.problems = tuple(problems)
        if len(self.problems) == 1:
            text = str(self.problems[0])
        else:
            text = f"{len(self.problems)} problems in the launch file:\n" + "\n".join(
                f"  {problem}" for problem in self.problems)
        super().__init__(text)


@dataclass(frozen=True)
class LaunchArgument:
    """A declared ``arg``: ``default`` ``None`` means the value must be given."""

    name: str
    default: str | None = None
    description: str = ""
    choices: tuple[str, ...] | None = None
    source: str = ""


@dataclass(frozen=True)
class NodeLaunch:
    """One node process, fully resolved: every substitution done, every path absolute.

    label : unique short name, the ``[label]`` prefix of the node's output lines.
    source : ``file:line`` of the ``node`` entry.
    program : what runs, ``(python, "-m", module)`` or ``(/abs/executable,)``.
    module : the module for ``python -m`` nodes, else ``None``.
    arguments : extra arguments before ``--ros-args`` (the entry's ``args``).
    name, namespace : node name and absolute namespace, or ``None`` for the node's own defaults.
    parameters : ``InlineParameter`` / ``ParameterFile`` in the order written (later ones win).
    remaps : ``(from, to)`` pairs.
    env : ``(NAME, value)`` pairs set on top of the launcher's environment.
    respawn, respawn_delay_s, respawn_max_delay_s : restart on exit, first delay and backoff cap (seconds).
    required : when it exits, everything stops (and the launch fails if its exit code is not 0).
    output : ``screen``, ``log`` or ``both``.
    """

    label: str
    source: str
    program: tuple[str, ...]
    module: str | None = None
    arguments: tuple[str, ...] = ()
    name: str | None = None
    namespace: str | None = None
    parameters: tuple[InlineParameter | ParameterFile, ...] = ()
    remaps: tuple[tuple[str, str], ...] = ()
    env: tuple[tuple[str, str], ...] = ()
    respawn: bool = False
    respawn_delay_s: float = 0.0
    respawn_max_delay_s: float = DEFAULT_RESPAWN_MAX_DELAY_S
    required: bool = False
    output: str = "screen"

    @property
    def full_name(self) -> str | None:
        """``/namespace/name`` (``/name`` without a namespace), or ``None`` when no name is set."""
        if self.name is None:
            return None
        return f"{(self.namespace or '').rstrip('/')}/{self.name}"

    @property
    def command(self) -> list[str]:
        """The argv of the process: program, ``args``, then ``--ros-args ...`` as launch_ros builds it."""
        return [*self.program, *self.arguments,
                *ros_arguments(name=self.name, namespace=self.namespace, parameters=self.parameters,
                               remaps=self.remaps)]

    @property
    def respawn_policy(self) -> RespawnPolicy:
        """Restart delays of this node (meaningful when ``respawn`` is true)."""
        return RespawnPolicy(base_delay_s=self.respawn_delay_s, max_delay_s=self.respawn_max_delay_s)


@dataclass(frozen=True)
class LaunchPlan:
    """A validated launch file: its declared arguments, their values, and the nodes to start in order."""

    path: str
    arguments: tuple[LaunchArgument, ...]
    values: Mapping[str, str]
    nodes: tuple[NodeLaunch, ...]


# ------------------------------------------------------------------------------------------------
# public functions
# ------------------------------------------------------------------------------------------------

def parse_launch_arguments(tokens: Sequence[str]) -> dict[str, str]:
    """``["rate:=10", "sim:=true"]`` -> ``{"rate": "10", "sim": "true"}``.

    Raises
    ------
    ValueError
        A token without ``:=``, with an empty or malformed name, or a name given twice.
    """
    values: dict[str, str] = {}
    for token in tokens:
        name, separator, value = token.partition(":=")
        if not separator or not _ARG_NAME.fullmatch(name):
            raise ValueError(f"launch arguments are written NAME:=VALUE (e.g. rate:=10); got {token!r}")
        if name in values:
            raise ValueError(f"launch argument {name!r} is given twice ({values[name]!r} and {value!r})")
        values[name] = value
    return values


def load_launch_file(path: str | os.PathLike, arguments: Mapping[str, str] | None = None, *,
                     environ: Mapping[str, str] | None = None, python: str | None = None,
                     cwd: str | os.PathLike | None = None) -> LaunchPlan:
    """Read, validate and resolve a launch file (and its includes) into a :class:`LaunchPlan`.

    Parameters
    ----------
    path : str or PathLike
        The top-level YAML launch file.
    arguments : mapping of str to str, optional
        Values of the top file's declared ``arg`` entries (``name:=value`` on the command line).
        A name the file does not declare is an error.
    environ : mapping, optional
        Environment for ``$(env ...)``, ``PATH`` lookups of executables and ``PYTHONPATH`` lookups of
        modules (default: ``os.environ``).
    python : str, optional
        Interpreter that runs ``module`` nodes (default: ``sys.executable``).
    cwd : str or PathLike, optional
        Working directory of the node processes, searched first for modules as ``python -m`` does
        (default: the current directory).

    Returns
    -------
    LaunchPlan

    Raises
    ------
    LaunchFileError
        Every problem found, each with file and line. Nothing has been started.
    """
    loader = _Loader(environ=os.environ if environ is None else environ, python=python or sys.executable,
                     cwd=os.fspath(cwd) if cwd is not None else os.getcwd())
    return loader.load_plan(os.fspath(path), dict(arguments or {}))


def declared_arguments(path: str | os.PathLike) -> tuple[LaunchArgument, ...]:
    """The ``arg`` entries of one launch file (not its includes), without needing any values.

    Raises
    ------
    LaunchFileError
        The file is missing, not YAML, or its ``arg`` entries are malformed.
    """
    loader = _Loader(environ=os.environ, python=sys.executable, cwd=os.getcwd())
    display = loader.display(os.path.abspath(os.fspath(path)))
    entries = loader.read_entries(os.path.abspath(os.fspath(path)), display)
    if loader.problems:
        raise LaunchFileError(loader.problems)
    found = []
    for index, entry in enumerate(entries or ()):
        if isinstance(entry, MarkedDict) and list(entry) == ["arg"] and isinstance(entry["arg"], MarkedDict):
            spec = entry["arg"]
            scope = _Scope(path=os.path.abspath(os.fspath(path)), display=display, given={}, given_from="")
            try:
                loader.check_keys("arg", spec)
                name = loader.text(scope, spec, "name", "arg", substitute_values=False)
                default = loader.text(scope, spec, "default", "arg", substitute_values=False) \
                    if "default" in spec else None
                description = loader.text(scope, spec, "description", "arg", substitute_values=False) \
                    if "description" in spec else ""
                choices = loader.choices(scope, spec)
            except _Fail as fail:
                loader.add(display, fail.line, fail.message)
                continue
            source = f"{display}:{entries.item_line(index)}"
            found.append(LaunchArgument(name, default, description, choices, source))
    if loader.problems:
        raise LaunchFileError(loader.problems)
    return tuple(found)


# ------------------------------------------------------------------------------------------------
# the loader
# ------------------------------------------------------------------------------------------------

class _Fail(Exception):
    """Abandon the current entry: a problem at ``line`` of the file being read."""

    def __init__(self, line: int | None, message: str):
        super().__init__(message)
        self.line, self.message = line, message


@dataclass
class _Scope:
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


@dataclass
class _NodeDraft:
    node: NodeLaunch
    display: str
    line: int


def _suggest(word: str, candidates: Sequence[str]) -> str:
    close = difflib.get_close_matches(word, list(candidates), n=1, cutoff=0.6)
    return f" (did you mean '{close[0]}'?)" if close else ""


def _type_name(value) -> str:
    if value is None:
        return "nothing (null)"
    if isinstance(value, dict):
        return "a mapping"
    if isinstance(value, list):
        return "a list"
    return f"{type(value).__name__} {value!r}"


class _Loader:
    def __init__(self, *, environ: Mapping[str, str], python: str, cwd: str):
        self.environ = environ
        self.python = python
        self.cwd = os.path.abspath(cwd)
        self.problems: list[LaunchProblem] = []
        self.drafts: list[_NodeDraft] = []
        self.include_stack: list[str] = []
        pythonpath = [entry for entry in environ.get("PYTHONPATH", "").split(os.pathsep) if entry]
        self.module_search_path = [self.cwd, *(os.path.join(self.cwd, entry) for entry in pythonpath), *sys.path]

    # --- bookkeeping --------------------------------------------------------------------------

    def add(self, display: str, line: int | None, message: str) -> None:
        if len(self.problems) < _MAX_PROBLEMS:
            self.problems.append(LaunchProblem(display, line, message))

    def display(self, absolute: str) -> str:
        relative = os.path.relpath(absolute, self.cwd)
        return absolute if relative.startswith("..") else relative

    # --- files --------------------------------------------------------------------------------

    def load_plan(self, path: str, given: dict[str, str]) -> LaunchPlan:
        absolute = os.path.abspath(path)
        display = self.display(absolute)
        scope = _Scope(path=absolute, display=display, given=given, given_from="the command line")
        if not os.path.isfile(absolute):
            raise LaunchFileError([LaunchProblem(display, None, "launch file not found")])
        if self.read_file(scope, namespace=""):
            for name in given:
                if name not in scope.declared:
                    declared = ", ".join(scope.declared) or "none"
                    self.add(display, None, f"command line: unknown launch argument {name!r}"
                                            f"{_suggest(name, list(scope.declared))}; {display} declares: {declared}")
        nodes = self.finish_nodes()
        if self.problems:
            raise LaunchFileError(self.problems)
        return LaunchPlan(path=display, arguments=tuple(scope.arguments), values=dict(scope.values),
                          nodes=nodes)

    def read_entries(self, absolute: str, display: str) -> MarkedList | None:
        """The ``launch:`` list of a file, or ``None`` after recording why it cannot be read."""
        try:
            document = load_marked_yaml(absolute)
        except YamlSyntaxError as exc:
            self.add(display, exc.line, str(exc))
            return None
        except OSError as exc:
            self.add(display, None, f"cannot read the launch file: {exc.strerror or exc}")
            return None
        if not isinstance(document, MarkedDict) or "launch" not in document:
            got = "keys " + ", ".join(map(str, document)) if isinstance(document, dict) else _type_name(document)
            self.add(display, getattr(document, "line", None) or 1,
                     f"launch file must be a mapping with one key 'launch' holding a list of entries; got {got}")
            return None
        for key in document:
            if key != "launch":
                self.add(display, document.key_line(key),
                         f"unknown top-level key {key!r}{_suggest(str(key), ['launch'])}; a launch file has only "
                         f"'launch:'")
        entries = document["launch"]
        if entries is None:
            return MarkedList()
        if not isinstance(entries, MarkedList):
            self.add(display, document.value_line("launch"),
                     f"launch: expected a list of entries; got {_type_name(entries)}")
            return None
        return entries

    def read_file(self, scope: _Scope, namespace: str) -> bool:
        """Run the entries of a file; False when the file itself could not be read (its args are unknown)."""
        entries = self.read_entries(scope.path, scope.display)
        if entries is None:
            return False
        self.include_stack.append(scope.path)
        try:
            self.run_entries(scope, entries, namespace, dict(scope.values), top_level=True)
        finally:
            self.include_stack.pop()
        return True

    # --- entries ------------------------------------------------------------------------------

    def entity(self, scope: _Scope, entries: MarkedList, index: int) -> tuple[str, MarkedDict]:
        """The kind and body of entry ``index``, checked for shape and keys (raises _Fail)."""
        entry, line = entries[index], entries.item_line(index)
        kinds = ", ".join(ENTITY_KEYS)
        if not isinstance(entry, MarkedDict) or not entry:
            raise _Fail(line, f"each launch entry is a mapping with one key ({kinds}); got {_type_name(entry)}")
        if len(entry) != 1:
            keys = ", ".join(map(str, entry))
            raise _Fail(line, f"a launch entry has exactly one key ({kinds}); got {keys} -- "
                              f"are the keys of the entry indented under it?")
        kind = next(iter(entry))
        if kind not in ENTITY_KEYS:
            raise _Fail(line, f"unknown entry {kind!r}{_suggest(str(kind), list(ENTITY_KEYS))}; known: {kinds}")
        body = entry[kind]
        if not isinstance(body, MarkedDict):
            raise _Fail(entry.value_line(kind), f"{kind}: expected a mapping of keys; got {_type_name(body)}"
                        + (" -- are its keys indented under it?" if body is None else ""))
        body.line = line  # the entity is "at" its "- node:" line (a block mapping starts a line below)
        self.check_keys(kind, body)
        return kind, body

    def check_keys(self, kind: str, body: MarkedDict, required: Sequence[str] | None = None,
                   allowed: Sequence[str] | None = None) -> None:
        if required is None:
            required, optional = ENTITY_KEYS[kind]
            allowed = (*required, *optional)
        for key in body:
            if key not in allowed:
                hint = _suggest(str(key), allowed)
                listing = "" if hint else f" (allowed: {', '.join(allowed)})"
                raise _Fail(body.key_line(key), f"{kind}: unknown key {key!r}{hint}{listing}")
        for key in required:
            if key not in body:
                raise _Fail(body.line, f"{kind}: missing required key {key!r}")

    def run_entries(self, scope: _Scope, entries: MarkedList, namespace: str, variables: dict[str, str], *,
                    top_level: bool) -> None:
        for index in range(len(entries)):
            try:
                kind, body = self.entity(scope, entries, index)
                if kind == "arg":
                    self.declare_argument(scope, body, variables, top_level)
                elif kind == "let":
                    if self.condition(scope, body, variables, "let"):
                        name = self.text(scope, body, "name", "let", variables=variables)
                        if not _ARG_NAME.fullmatch(name):
                            raise _Fail(body.value_line("name"), f"let: {name!r} is not a valid name")
                        variables[name] = self.text(scope, body, "value", "let", variables=variables)
                elif kind == "include":
                    if self.condition(scope, body, variables, "include"):
                        self.include(scope, body, namespace, variables)
                elif kind == "group":
                    children = body["children"]
                    if not isinstance(children, MarkedList):
                        raise _Fail(body.value_line("children"),
                                    f"group: children must be a list of entries; got {_type_name(children)}")
                    if self.condition(scope, body, variables, "group"):
                        inner = self.join_namespace(scope, body, namespace, variables, "group")
                        self.run_entries(scope, children, inner, dict(variables), top_level=False)
                    else:
                        self.check_structure(scope, children)
                elif kind == "node":
                    if self.condition(scope, body, variables, "node"):
                        self.node(scope, body, namespace, variables)
                    else:
                        self.node_program_keys(body)
            except _Fail as fail:
                self.add(scope.display, fail.line, fail.message)

    def check_structure(self, scope: _Scope, entries: MarkedList) -> None:
        """Shape and key checks only, for entries a false condition skips."""
        for index in range(len(entries)):
            try:
                kind, body = self.entity(scope, entries, index)
                if kind == "arg":
                    raise _Fail(entries.item_line(index), "arg: declare arguments at the top level of the file, "
                                                          "not inside a group")
                if kind == "group" and isinstance(body["children"], MarkedList):
                    self.check_structure(scope, body["children"])
                if kind == "node":
                    self.node_program_keys(body)
            except _Fail as fail:
                self.add(scope.display, fail.line, fail.message)

    # --- values -------------------------------------------------------------------------------

    def context(self, scope: _Scope, variables: Mapping[str, str]) -> SubstitutionContext:
        return SubstitutionContext(variables=variables, launch_file_dir=scope.directory, environ=self.environ)

    def substitute(self, scope: _Scope, text: str, variables: Mapping[str, str], line: int, where: str) -> str:
        try:
            return substitute(text, self.context(scope, variables))
        except SubstitutionError as exc:
            raise _Fail(line, f"{where}: {exc}") from None

    def text(self, scope: _Scope, body: MarkedDict, key: str, kind: str, *, variables: Mapping[str, str] = (),
             substitute_values: bool = True) -> str:
        """The value of ``key`` as text: strings substituted; numbers and booleans written as YAML would."""
        value, line = body[key], body.value_line(key)
        if isinstance(value, bool):
            return "true" if value else "false"
        if isinstance(value, int | float):
            return str(value)
        if not isinstance(value, str):
            raise _Fail(line, f"{kind}: {key} must be text; got {_type_name(value)}")
        if not substitute_values:
            return value
        return self.substitute(scope, value, dict(variables), line, f"{kind} {key}")

    def boolean(self, scope: _Scope, body: MarkedDict, key: str, kind: str, variables, default: bool) -> bool:
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
            raise _Fail(line, f"{kind}: {key} must be true or false (or 1 / 0); got {text!r}")
        raise _Fail(line, f"{kind}: {key} must be true or false; got {_type_name(value)}")

    def seconds(self, scope: _Scope, body: MarkedDict, key: str, kind: str, variables, default: float) -> float:
        if key not in body:
            return default
        value, line = body[key], body.value_line(key)
        if isinstance(value, str):
            text = self.substitute(scope, value, variables, line, f"{kind} {key}")
            try:
                value = float(text)
            except ValueError:
                raise _Fail(line, f"{kind}: {key} must be a number of seconds; got {text!r}") from None
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise _Fail(line, f"{kind}: {key} must be a number of seconds; got {_type_name(value)}")
        if not 0 <= value < float("inf"):
            raise _Fail(line, f"{kind}: {key} must be a finite number of seconds >= 0; got {value}")
        return float(value)

    def condition(self, scope: _Scope, body: MarkedDict, variables, kind: str) -> bool:
        if "if" in body and "unless" in body:
            raise _Fail(body.key_line("unless"), f"{kind}: use either 'if' or 'unless', not both")
        if "if" in body:
            return self.boolean(scope, body, "if", kind, variables, True)
        if "unless" in body:
            return not self.boolean(scope, body, "unless", kind, variables, False)
        return True

    def choices(self, scope: _Scope, body: MarkedDict) -> tuple[str, ...] | None:
        if "choices" not in body:
            return None
        value = body["choices"]
        if not isinstance(value, list) or not value or any(
                isinstance(item, list | dict) or item is None for item in value):
            raise _Fail(body.value_line("choices"), f"arg: choices must be a non-empty list of values; "
                                                    f"got {_type_name(value)}")
        return tuple(("true" if item else "false") if isinstance(item, bool) else str(item) for item in value)

    def list_of_mappings(self, body: MarkedDict, key: str, kind: str) -> MarkedList:
        value = body[key]
        if value is None:
            return MarkedList()
        if not isinstance(value, MarkedList):
            raise _Fail(body.value_line(key), f"{kind}: {key} must be a list of mappings; got {_type_name(value)}")
        for index, item in enumerate(value):
            if not isinstance(item, MarkedDict):
                raise _Fail(value.item_line(index), f"{kind} {key}: each item must be a mapping; "
                                                    f"got {_type_name(item)}")
        return value

    # --- arg / include / group namespace --------------------------------------------------------

    def declare_argument(self, scope: _Scope, body: MarkedDict, variables: dict[str, str], top_level: bool) -> None:
        if not top_level:
            raise _Fail(body.line, "arg: declare arguments at the top level of the file, not inside a group")
        name = self.text(scope, body, "name", "arg", substitute_values=False)
        if not _ARG_NAME.fullmatch(name):
            raise _Fail(body.value_line("name"), f"arg: {name!r} is not a valid argument name "
                                                 f"(letters, digits, _ . -; not starting with a digit)")
        if name in scope.declared:
            raise _Fail(body.key_line("name"),
                        f"arg: {name!r} is declared twice (first at line {scope.declared[name]})")
        scope.declared[name] = body.line
        description = self.text(scope, body, "description", "arg", substitute_values=False) \
            if "description" in body else ""
        default = self.text(scope, body, "default", "arg", variables=variables) if "default" in body else None
        choices = self.choices(scope, body)
        scope.arguments.append(LaunchArgument(name, default, description, choices, f"{scope.display}:{body.line}"))
        if name in scope.given:
            value = scope.given[name]
        elif default is not None:
            value = default
        else:
            variables[name] = ""  # keep later uses from piling up "undeclared" problems
            raise _Fail(body.line, f"arg {name!r} has no default and no value was given; "
                                   f"{scope.given_from} must pass it ({name}:=VALUE)")
        if choices is not None and value not in choices:
            variables[name] = value
            raise _Fail(body.line, f"arg {name!r} must be one of {', '.join(choices)}; got {value!r}")
        variables[name] = scope.values[name] = value

    def include(self, scope: _Scope, body: MarkedDict, namespace: str, variables: dict[str, str]) -> None:
        file_text = self.text(scope, body, "file", "include", variables=variables)
        line = body.value_line("file")
        if not file_text:
            raise _Fail(line, "include: file is empty")
        absolute = os.path.normpath(os.path.join(scope.directory, file_text))
        if not os.path.isfile(absolute):
            raise _Fail(line, f"include: file {file_text!r} not found (looked for {absolute}; a relative path is "
                              f"relative to the including file)")
        if not absolute.endswith((".yaml", ".yml")):
            raise _Fail(line, f"include: only YAML launch files (.yaml, .yml) can be included; got {file_text!r}")
        if absolute in self.include_stack:
            chain = " -> ".join(self.display(path) for path in [*self.include_stack, absolute])
            raise _Fail(line, f"include: {file_text!r} includes itself ({chain})")
        given, given_lines = {}, {}
        if "arg" in body:
            for item in self.list_of_mappings(body, "arg", "include"):
                self.check_keys("include arg", item, required=("name", "value"), allowed=("name", "value"))
                name = self.text(scope, item, "name", "include arg", variables=variables)
                if name in given:
                    raise _Fail(item.key_line("name"), f"include: argument {name!r} is passed twice")
                given[name] = self.text(scope, item, "value", "include arg", variables=variables)
                given_lines[name] = item.line
        child = _Scope(path=absolute, display=self.display(absolute), given=given,
                       given_from=f"the include at {scope.display}:{body.line}")
        if not self.read_file(child, namespace):
            return  # its declarations are unknown
        for name, arg_line in given_lines.items():
            if name not in child.declared:
                declared = ", ".join(child.declared) or "none"
                self.add(scope.display, arg_line, f"include: {file_text!r} declares no argument {name!r}"
                                                  f"{_suggest(name, list(child.declared))} (declared: {declared})")

    def join_namespace(self, scope: _Scope, body: MarkedDict, namespace: str, variables, kind: str) -> str:
        """The namespace in effect inside ``body``: its own (absolute, or relative to ``namespace``)."""
        if "namespace" not in body:
            return namespace
        text = self.text(scope, body, "namespace", kind, variables=variables).strip()
        if not text:
            return namespace
        joined = text if text.startswith("/") else f"{namespace.rstrip('/')}/{text}"
        joined = joined.rstrip("/") or "/"
        if not _NAMESPACE.fullmatch(joined):
            raise _Fail(body.value_line("namespace"), f"{kind}: namespace {joined!r} is not valid: components are "
                                                      f"letters, digits and _, not starting with a digit, "
                                                      f"separated by /")
        return joined

    # --- node -----------------------------------------------------------------------------------

    def node_program_keys(self, body: MarkedDict) -> None:
        if ("module" in body) == ("executable" in body):
            raise _Fail(body.line, "node: give exactly one of 'module' (run with python -m) or 'executable'"
                        + (" -- not both" if "module" in body else ""))

    def node(self, scope: _Scope, body: MarkedDict, namespace: str, variables: dict[str, str]) -> None:
        self.node_program_keys(body)
        kind = "node"
        if "module" in body:
            module = self.text(scope, body, "module", kind, variables=variables).strip()
            problem = module_problem(module, self.module_search_path)
            if problem:
                raise _Fail(body.value_line("module"), f"node: {problem}")
            program, default_label = (self.python, "-m", module), module.rsplit(".", 1)[-1]
        else:
            module = None
            executable = self.text(scope, body, "executable", kind, variables=variables).strip()
            program, default_label = (self.find_executable(scope, executable, body.value_line("executable")),), \
                os.path.basename(executable)
        arguments = self.arguments(scope, body, variables) if "args" in body else ()
        name = None
        if "name" in body:
            name = self.text(scope, body, "name", kind, variables=variables).strip()
            if not _NAME.fullmatch(name):
                raise _Fail(body.value_line("name"), f"node: name {name!r} is not a valid node name: letters, digits "
                                                     f"and _, not starting with a digit, no /")
        node_namespace = self.join_namespace(scope, body, namespace, variables, kind) or None
        parameters = tuple(self.parameters(scope, body, variables)) if "param" in body else ()
        remaps = tuple(self.remaps(scope, body, variables)) if "remap" in body else ()
        env = tuple(self.environment(scope, body, variables)) if "env" in body else ()
        respawn = self.boolean(scope, body, "respawn", kind, variables, False)
        required = self.boolean(scope, body, "required", kind, variables, False)
        if respawn and required:
            raise _Fail(body.key_line("required"), "node: a node cannot be both required and respawn: true "
                                                   "(required stops everything when it exits; respawn restarts it)")
        delay = self.seconds(scope, body, "respawn_delay", kind, variables, 0.0)
        cap = self.seconds(scope, body, "respawn_max_delay", kind, variables, max(DEFAULT_RESPAWN_MAX_DELAY_S, delay))
        if cap < delay:
            raise _Fail(body.value_line("respawn_max_delay"), f"node: respawn_max_delay ({cap} s) must be >= "
                                                              f"respawn_delay ({delay} s)")
        output = self.text(scope, body, "output", kind, variables=variables).strip() if "output" in body else "screen"
        if output not in OUTPUT_MODES:
            raise _Fail(body.value_line("output"), f"node: output must be one of {', '.join(OUTPUT_MODES)}; "
                                                   f"got {output!r}{_suggest(output, OUTPUT_MODES)}")
        node = NodeLaunch(label=name or default_label, source=f"{scope.display}:{body.line}", program=program,
                          module=module, arguments=arguments, name=name, namespace=node_namespace,
                          parameters=parameters, remaps=remaps, env=env, respawn=respawn, respawn_delay_s=delay,
                          respawn_max_delay_s=cap, required=required, output=output)
        self.drafts.append(_NodeDraft(node, scope.display, body.line))

    def find_executable(self, scope: _Scope, executable: str, line: int) -> str:
        if not executable:
            raise _Fail(line, "node: executable is empty")
        if os.sep in executable or (os.altsep and os.altsep in executable):
            path = os.path.normpath(os.path.join(scope.directory, os.path.expanduser(executable)))
            if not os.path.isfile(path):
                raise _Fail(line, f"node: executable {executable!r} not found (looked for {path}; a relative path "
                                  f"is relative to the launch file)")
            if not os.access(path, os.X_OK):
                raise _Fail(line, f"node: executable {path} is not executable (chmod +x it)")
            return path
        found = shutil.which(executable, path=self.environ.get("PATH", os.defpath))
        if found is None:
            raise _Fail(line, f"node: executable {executable!r} not found on PATH")
        return os.path.abspath(found)

    def arguments(self, scope: _Scope, body: MarkedDict, variables) -> tuple[str, ...]:
        value, line = body["args"], body.value_line("args")
        if isinstance(value, str):
            text = self.substitute(scope, value, variables, line, "node args")
            try:
                return tuple(shlex.split(text))
            except ValueError as exc:
                raise _Fail(line, f"node: args {text!r} cannot be split into words: {exc}") from None
        if isinstance(value, list):
            words = []
            for index, item in enumerate(value):
                if isinstance(item, list | dict) or item is None:
                    raise _Fail(value.item_line(index), f"node: each item of args must be text; got {_type_name(item)}")
                if isinstance(item, str):
                    words.append(self.substitute(scope, item, variables, value.item_line(index), "node args"))
                else:
                    words.append(("true" if item else "false") if isinstance(item, bool) else str(item))
            return tuple(words)
        raise _Fail(line, f"node: args must be text or a list of words; got {_type_name(value)}")

    def parameters(self, scope: _Scope, body: MarkedDict, variables, prefix: str = "", key: str = "param"):
        for item in self.list_of_mappings(body, key, "node"):
            self.check_keys("param", item, required=(), allowed=("name", "value", "param", "from"))
            if "from" in item:
                if len(item) > 1:
                    raise _Fail(item.line, "param: 'from' (a parameter file) stands alone; put 'name'/'value' in "
                                           "their own item")
                if prefix:
                    raise _Fail(item.line, "param: a parameter file ('from') cannot be nested under a parameter name")
                yield self.parameter_file(scope, item, variables)
                continue
            if "name" not in item:
                raise _Fail(item.line, "param: missing required key 'name' (or 'from' for a parameter file)")
            if ("value" in item) == ("param" in item):
                raise _Fail(item.line, "param: give exactly one of 'value' or nested 'param'")
            name = self.text(scope, item, "name", "param", variables=variables).strip()
            if not _PARAM_NAME.fullmatch(name):
                raise _Fail(item.value_line("name"), f"param: {name!r} is not a valid parameter name")
            full = f"{prefix}{name}"
            if "param" in item:
                yield from self.parameters(scope, item, variables, prefix=f"{full}.")
            else:
                yield InlineParameter(full, self.parameter_value(scope, item, variables, full))

    def parameter_value(self, scope: _Scope, item: MarkedDict, variables, name: str):
        value, line = item["value"], item.value_line("value")
        if isinstance(value, list):
            values = [self.parameter_scalar(scope, entry, variables, value.item_line(index), name)
                      for index, entry in enumerate(value)]
            kinds = {type(entry) for entry in values}
            if len(kinds) > 1:
                listing = " and ".join(sorted(kind.__name__ for kind in kinds))
                raise _Fail(line, f"param {name!r}: array items must all have one type (bool, int, float or str); "
                                  f"got {listing}")
            return values
        return self.parameter_scalar(scope, value, variables, line, name)

    def parameter_scalar(self, scope: _Scope, value, variables, line: int, name: str):
        if value is None:
            raise _Fail(line, f"param {name!r} has no value (write value: ...)")
        if isinstance(value, dict):
            raise _Fail(line, f"param {name!r}: a value cannot be a mapping; nest parameters with 'param:' "
                              f"items instead")
        if isinstance(value, list):
            raise _Fail(line, f"param {name!r}: arrays cannot be nested")
        if isinstance(value, str) and has_substitution(value):
            text = self.substitute(scope, value, variables, line, f"param {name}")
            try:  # like ROS 2: text produced by a substitution is typed by YAML ("10" -> 10)
                typed = yaml.safe_load(text)
            except yaml.YAMLError:
                return text
            return typed if isinstance(typed, PARAMETER_SCALAR_TYPES) else text
        if not isinstance(value, PARAMETER_SCALAR_TYPES):
            raise _Fail(line, f"param {name!r}: a value must be bool, int, float or text; got {_type_name(value)} "
                              f"(quote it to make it text)")
        return value

    def parameter_file(self, scope: _Scope, item: MarkedDict, variables) -> ParameterFile:
        text = self.text(scope, item, "from", "param", variables=variables)
        line = item.value_line("from")
        path = os.path.normpath(os.path.join(scope.directory, os.path.expanduser(text)))
        if not os.path.isfile(path):
            raise _Fail(line, f"param: parameter file {text!r} not found (looked for {path}; a relative path is "
                              f"relative to the launch file)")
        try:
            content = yaml.safe_load(Path(path).read_text(encoding="utf-8"))
        except (yaml.YAMLError, OSError, UnicodeDecodeError) as exc:
            raise _Fail(line, f"param: parameter file {text!r} cannot be read as YAML: "
                              f"{str(exc).splitlines()[0]}") from None
        if not isinstance(content, dict) or not any(
                isinstance(section, dict) and "ros__parameters" in section for section in content.values()):
            raise _Fail(line, f"param: parameter file {text!r} is not a ROS 2 parameter file "
                              f"(expected NODE_NAME: {{ros__parameters: {{...}}}}, or '/**:' for every node)")
        return ParameterFile(path)

    def remaps(self, scope: _Scope, body: MarkedDict, variables):
        for item in self.list_of_mappings(body, "remap", "node"):
            self.check_keys("remap", item, required=("from", "to"), allowed=("from", "to"))
            pair = []
            for key in ("from", "to"):
                text = self.text(scope, item, key, "remap", variables=variables).strip()
                if not text or ":=" in text or any(char.isspace() for char in text):
                    raise _Fail(item.value_line(key), f"remap: {key} must be a non-empty name without spaces "
                                                      f"or ':='; got {text!r}")
                pair.append(text)
            yield tuple(pair)

    def environment(self, scope: _Scope, body: MarkedDict, variables):
        for item in self.list_of_mappings(body, "env", "node"):
            self.check_keys("env", item, required=("name", "value"), allowed=("name", "value"))
            name = self.text(scope, item, "name", "env", variables=variables).strip()
            if not _ENV_NAME.fullmatch(name):
                raise _Fail(item.value_line("name"), f"env: {name!r} is not a valid environment variable name")
            yield name, self.text(scope, item, "value", "env", variables=variables)

    # --- the whole plan -------------------------------------------------------------------------

    def finish_nodes(self) -> tuple[NodeLaunch, ...]:
        """Check node names are unique; make labels unique (``name``, then ``ns/name``, then ``-2``...)."""
        seen: dict[str, _NodeDraft] = {}
        for draft in self.drafts:
            full = draft.node.full_name
            if full is None:
                continue
            if full in seen:
                first = seen[full]
                self.add(draft.display, draft.line, f"node: name {full!r} is used twice (first at "
                                                    f"{first.node.source}); give each node its own name or namespace")
            else:
                seen[full] = draft
        original = [draft.node.label for draft in self.drafts]
        labels = list(original)
        for index, draft in enumerate(self.drafts):
            if original.count(draft.node.label) > 1 and draft.node.name and draft.node.namespace:
                labels[index] = draft.node.full_name.lstrip("/")
        taken: set[str] = set()
        nodes = []
        for label, draft in zip(labels, self.drafts):
            unique, count = label, 1
            while unique in taken:
                count += 1
                unique = f"{label}-{count}"
            taken.add(unique)
            nodes.append(dataclasses.replace(draft.node, label=unique))
        return tuple(nodes)
