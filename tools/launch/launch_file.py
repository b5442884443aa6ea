"""Launch files: parse, validate and resolve a YAML launch file into a :class:`LaunchPlan`.

The format is ROS 2's YAML front end, a documented subset (``docs/launch.md`` describes every key)::

    launch:
      - arg: {name: rate, default: "10", description: frames per second}
      - arg: {name: method, default: mf, choice: [{value: mf}, {value: nt}]}
      - include: {file: $(dirname)/camera.yaml, arg: [{name: rate, value: "$(var rate)"}]}
      - group:
          - push_ros_namespace: {namespace: /scanner}
          - node:
              pkg: dptpu
              exec: phase                 # python -m dptpu.nodes.phase
              name: phase
              param: [{name: min_modulation, value: 5.0}, {from: $(dirname)/params.yaml}]
              remap: [{from: /camera/image_raw, to: /sim/image}]
              respawn: true
              respawn_delay: 1.0

The project's keys from before it followed ROS 2 (``module``, ``executable``, ``required``, ``choices``, a group's
``namespace``) are refused with the ROS 2 spelling (``OLD_KEYS``).

Everything is checked before anything starts: unknown and missing keys, types, ``$(...)``
substitutions, that modules (``python -m``), executables, included files and parameter files exist,
that node names are unique. Every problem found becomes one :class:`LaunchProblem` naming the file and
line, e.g. ``sim_rig.yaml:14: node: unknown key 'remapp' (did you mean 'remap'?)``, and all of them are
raised together as one :class:`LaunchFileError`.

Scoping: each file sees only its own ``arg`` values (from the command line for the top file, from the
``include``'s ``arg`` list for an included one, else the default) and the ``let`` values set before the
use; a ``group`` scopes the ``let`` and ``push_ros_namespace`` inside it; a namespace pushed applies to every
node after it in its list, included files too.
"""
from __future__ import annotations

import os
import re
import sys
from collections.abc import Mapping, Sequence

from .argument_types import argument_type_problem
from .launch_plan import (
    OUTPUT_MODES,
    LaunchArgument,
    LaunchFileError,
    LaunchPlan,
    LaunchProblem,
    NodeLaunch,
)
from .launch_values import ENTITY_KEYS, EntryFailure, FileScope, ValueReader, suggest, type_name
from .marked_yaml import MarkedDict, MarkedList, YamlSyntaxError, load_marked_yaml
from .node_entries import NodeReader

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

_MAX_PROBLEMS = 50
#: The entity that pushes a namespace onto the nodes after it (both ROS 2 spellings).
PUSH_NAMESPACE = ("push_ros_namespace", "push-ros-namespace")
_ARG_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_.\-]*")


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
    loader = LaunchLoader(environ=os.environ if environ is None else environ, python=python or sys.executable,
                     cwd=os.fspath(cwd) if cwd is not None else os.getcwd())
    return loader.load_plan(os.fspath(path), dict(arguments or {}))


def declared_arguments(path: str | os.PathLike) -> tuple[LaunchArgument, ...]:
    """The ``arg`` entries of one launch file (not its includes), without needing any values.

    Raises
    ------
    LaunchFileError
        The file is missing, not YAML, or its ``arg`` entries are malformed.
    """
    loader = LaunchLoader(environ=os.environ, python=sys.executable, cwd=os.getcwd())
    display = loader.display(os.path.abspath(os.fspath(path)))
    entries = loader.read_entries(os.path.abspath(os.fspath(path)), display)
    if loader.problems or entries is None:  # None comes with a recorded problem
        raise LaunchFileError(loader.problems)
    found = []
    for index, entry in enumerate(entries):
        if isinstance(entry, MarkedDict) and list(entry) == ["arg"] and isinstance(entry["arg"], MarkedDict):
            spec = entry["arg"]
            scope = FileScope(path=os.path.abspath(os.fspath(path)), display=display, given={}, given_from="")
            try:
                loader.values.check_keys("arg", spec)
                name = loader.values.text(scope, spec, "name", "arg", substitute_values=False)
                default = loader.values.text(scope, spec, "default", "arg", substitute_values=False) \
                    if "default" in spec else None
                description = loader.values.text(scope, spec, "description", "arg", substitute_values=False) \
                    if "description" in spec else ""
                choices = loader.values.choices(scope, spec)
            except EntryFailure as fail:
                loader.add(display, fail.line, fail.message)
                continue
            source = f"{display}:{entries.item_line(index)}"
            found.append(LaunchArgument(name, default, description, choices, source))
    if loader.problems:
        raise LaunchFileError(loader.problems)
    return tuple(found)


class LaunchLoader:
    """Reads a launch file and its includes: files, entries, ``arg``/``let``/``include``/``group``; every problem
    recorded in :attr:`problems` (file and line) rather than raised at the first.

    ``values`` reads the keys of an entry, ``nodes`` the ``node`` entries.
    """

    def __init__(self, *, environ: Mapping[str, str], python: str, cwd: str):
        self.environ = environ
        self.python = python
        self.cwd = os.path.abspath(cwd)
        self.problems: list[LaunchProblem] = []
        self.include_stack: list[str] = []
        pythonpath = [entry for entry in environ.get("PYTHONPATH", "").split(os.pathsep) if entry]
        self.module_search_path = [self.cwd, *(os.path.join(self.cwd, entry) for entry in pythonpath), *sys.path]
        self.values = ValueReader(environ)
        self.nodes = NodeReader(self.values, python=python, module_search_path=self.module_search_path,
                                environ=environ)

    def add(self, display: str, line: int | None, message: str) -> None:
        if len(self.problems) < _MAX_PROBLEMS:
            self.problems.append(LaunchProblem(display, line, message))

    def display(self, absolute: str) -> str:
        relative = os.path.relpath(absolute, self.cwd)
        return absolute if relative.startswith("..") else relative

    def load_plan(self, path: str, given: dict[str, str]) -> LaunchPlan:
        absolute = os.path.abspath(path)
        display = self.display(absolute)
        scope = FileScope(path=absolute, display=display, given=given, given_from="the command line")
        if not os.path.isfile(absolute):
            raise LaunchFileError([LaunchProblem(display, None, "launch file not found")])
        if self.read_file(scope, namespace=""):
            for name in given:
                if name not in scope.declared:
                    declared = ", ".join(scope.declared) or "none"
                    self.add(display, None, f"command line: unknown launch argument {name!r}"
                                            f"{suggest(name, list(scope.declared))}; {display} declares: {declared}")
        nodes = self.nodes.finish_nodes(self.add)
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
            got = "keys " + ", ".join(map(str, document)) if isinstance(document, dict) else type_name(document)
            self.add(display, getattr(document, "line", None) or 1,
                     f"launch file must be a mapping with one key 'launch' holding a list of entries; got {got}")
            return None
        for key in document:
            if key != "launch":
                self.add(display, document.key_line(key),
                         f"unknown top-level key {key!r}{suggest(str(key), ['launch'])}; a launch file has only "
                         f"'launch:'")
        entries = document["launch"]
        if entries is None:
            return MarkedList()
        if not isinstance(entries, MarkedList):
            self.add(display, document.value_line("launch"),
                     f"launch: expected a list of entries; got {type_name(entries)}")
            return None
        return entries

    def read_file(self, scope: FileScope, namespace: str) -> bool:
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

    def entity(self, scope: FileScope, entries: MarkedList, index: int) -> tuple[str, MarkedDict]:
        """The kind and body of entry ``index``, checked for shape and keys (raises EntryFailure)."""
        entry, line = entries[index], entries.item_line(index)
        kinds = ", ".join(ENTITY_KEYS)
        if not isinstance(entry, MarkedDict) or not entry:
            raise EntryFailure(line, f"each launch entry is a mapping with one key ({kinds}); got {type_name(entry)}")
        if len(entry) != 1:
            keys = ", ".join(map(str, entry))
            raise EntryFailure(line, f"a launch entry has exactly one key ({kinds}); got {keys} -- "
                                     f"are the keys of the entry indented under it?")
        kind = next(iter(entry))
        if kind not in ENTITY_KEYS:
            raise EntryFailure(line, f"unknown entry {kind!r}{suggest(str(kind), list(ENTITY_KEYS))}; known: {kinds}")
        body = entry[kind]
        if kind == "group" and isinstance(body, MarkedList):  # ROS 2's short form: the group is its children
            children = body
            body = MarkedDict(children=children)
            body.key_lines["children"] = body.value_lines["children"] = children.line
        if not isinstance(body, MarkedDict):
            raise EntryFailure(entry.value_line(kind), f"{kind}: expected a mapping of keys; got {type_name(body)}"
                               + (" -- are its keys indented under it?" if body is None else ""))
        body.line = line  # the entity is "at" its "- node:" line (a block mapping starts a line below)
        self.values.check_keys(kind, body)
        return kind, body

    def run_entries(self, scope: FileScope, entries: MarkedList, namespace: str, variables: dict[str, str], *,
                    top_level: bool) -> None:
        for index in range(len(entries)):
            try:
                kind, body = self.entity(scope, entries, index)
                if kind in PUSH_NAMESPACE:  # for the entries after it in this list (a group's, or the file's)
                    if self.values.condition(scope, body, variables, kind):
                        namespace = self.values.join_namespace(scope, body, namespace, variables, kind)
                elif kind == "arg":
                    self.declare_argument(scope, body, variables, top_level)
                elif kind == "let":
                    if self.values.condition(scope, body, variables, "let"):
                        name = self.values.text(scope, body, "name", "let", variables=variables)
                        if not _ARG_NAME.fullmatch(name):
                            raise EntryFailure(body.value_line("name"), f"let: {name!r} is not a valid name")
                        variables[name] = self.values.text(scope, body, "value", "let", variables=variables)
                elif kind == "include":
                    if self.values.condition(scope, body, variables, "include"):
                        self.include(scope, body, namespace, variables)
                elif kind == "group":
                    children = body["children"]
                    if not isinstance(children, MarkedList):
                        raise EntryFailure(body.value_line("children"),
                                           f"group: children must be a list of entries; got {type_name(children)}")
                    if self.values.condition(scope, body, variables, "group"):
                        self.run_entries(scope, children, namespace, dict(variables), top_level=False)
                    else:
                        self.check_structure(scope, children)
                elif kind == "node":
                    if self.values.condition(scope, body, variables, "node"):
                        self.nodes.node(scope, body, namespace, variables)
                    else:
                        self.nodes.node_program_keys(body)
            except EntryFailure as fail:
                self.add(scope.display, fail.line, fail.message)

    def check_structure(self, scope: FileScope, entries: MarkedList) -> None:
        """Shape and key checks only, for entries a false condition skips."""
        for index in range(len(entries)):
            try:
                kind, body = self.entity(scope, entries, index)
                if kind == "arg":
                    raise EntryFailure(entries.item_line(index), "arg: declare arguments at the top level of the file, "
                                                                 "not inside a group")
                if kind == "group" and isinstance(body["children"], MarkedList):
                    self.check_structure(scope, body["children"])
                if kind == "node":
                    self.nodes.node_program_keys(body)
            except EntryFailure as fail:
                self.add(scope.display, fail.line, fail.message)

    def declare_argument(self, scope: FileScope, body: MarkedDict, variables: dict[str, str], top_level: bool) -> None:
        if not top_level:
            raise EntryFailure(body.line, "arg: declare arguments at the top level of the file, not inside a group")
        name = self.values.text(scope, body, "name", "arg", substitute_values=False)
        if not _ARG_NAME.fullmatch(name):
            raise EntryFailure(body.value_line("name"), f"arg: {name!r} is not a valid argument name "
                                                        f"(letters, digits, _ . -; not starting with a digit)")
        if name in scope.declared:
            raise EntryFailure(body.key_line("name"),
                               f"arg: {name!r} is declared twice (first at line {scope.declared[name]})")
        scope.declared[name] = body.line
        description = self.values.text(scope, body, "description", "arg", substitute_values=False) \
            if "description" in body else ""
        default = self.values.text(scope, body, "default", "arg", variables=variables) if "default" in body else None
        choices = self.values.choices(scope, body)
        scope.arguments.append(LaunchArgument(name, default, description, choices, f"{scope.display}:{body.line}"))
        if name in scope.given:
            value = scope.given[name]
        elif default is not None:
            value = default
        else:
            variables[name] = ""  # keep later uses from piling up "undeclared" problems
            raise EntryFailure(body.line, f"arg {name!r} has no default and no value was given; "
                                          f"{scope.given_from} must pass it ({name}:=VALUE)")
        if choices is not None and value not in choices:
            variables[name] = value
            raise EntryFailure(body.line, f"arg {name!r} must be one of {', '.join(choices)}; got {value!r}")
        problem = argument_type_problem(name, default, value) if name in scope.given else None
        if problem:  # the default's type: a value a statically typed parameter would refuse at start-up
            variables[name] = value
            raise EntryFailure(body.line, problem)
        variables[name] = scope.values[name] = value

    def include(self, scope: FileScope, body: MarkedDict, namespace: str, variables: dict[str, str]) -> None:
        file_text = self.values.text(scope, body, "file", "include", variables=variables)
        line = body.value_line("file")
        if not file_text:
            raise EntryFailure(line, "include: file is empty")
        absolute = os.path.normpath(os.path.join(scope.directory, file_text))
        if not os.path.isfile(absolute):
            raise EntryFailure(line,
                               f"include: file {file_text!r} not found (looked for {absolute}; a relative path is "
                               f"relative to the including file)")
        if not absolute.endswith((".yaml", ".yml")):
            raise EntryFailure(line,
                               f"include: only YAML launch files (.yaml, .yml) can be included; got {file_text!r}")
        if absolute in self.include_stack:
            chain = " -> ".join(self.display(path) for path in [*self.include_stack, absolute])
            raise EntryFailure(line, f"include: {file_text!r} includes itself ({chain})")
        given, given_lines = {}, {}
        if "arg" in body:
            for item in self.values.list_of_mappings(body, "arg", "include"):
                self.values.check_keys("include arg", item, required=("name", "value"), allowed=("name", "value"))
                name = self.values.text(scope, item, "name", "include arg", variables=variables)
                if name in given:
                    raise EntryFailure(item.key_line("name"), f"include: argument {name!r} is passed twice")
                given[name] = self.values.text(scope, item, "value", "include arg", variables=variables)
                given_lines[name] = item.line
        child = FileScope(path=absolute, display=self.display(absolute), given=given,
                       given_from=f"the include at {scope.display}:{body.line}")
        if not self.read_file(child, namespace):
            return  # its declarations are unknown
        for name, arg_line in given_lines.items():
            if name not in child.declared:
                declared = ", ".join(child.declared) or "none"
                self.add(scope.display, arg_line, f"include: {file_text!r} declares no argument {name!r}"
                                                  f"{suggest(name, list(child.declared))} (declared: {declared})")
