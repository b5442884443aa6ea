"""The ``node`` entry: its program (module or executable), arguments, parameters, remaps, environment, respawn.

:class:`NodeReader` turns each ``node`` entry into a :class:`~.launch_plan.NodeLaunch` and, once every file is
read, checks that node names are unique and gives each node a unique label.
"""

from __future__ import annotations

import dataclasses
import functools
import importlib.util
import os
import pkgutil
import re
import shlex
import shutil
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import yaml

from .command_line import PARAMETER_SCALAR_TYPES, InlineParameter, ParameterFile
from .installed import PACKAGE_NAME
from .launch_plan import DEFAULT_RESPAWN_MAX_DELAY_S, OUTPUT_MODES, NodeLaunch
from .launch_values import EntryFailure, FileScope, ValueReader, suggest, type_name
from .marked_yaml import MarkedDict, MarkedList
from .python_modules import module_problem
from .substitutions import has_substitution

__all__ = ["NODES_PACKAGE", "NodeDraft", "NodeReader", "dptpu_nodes"]

_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
#: ``pkg: dptpu``'s executables are the modules of this package.
NODES_PACKAGE = "dptpu.nodes"
_PARAM_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*")
_ENV_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
#: ``pkg: dptpu``'s executables are the modules of this package.
NODES_PACKAGE = "dptpu.nodes"


@functools.cache
def dptpu_nodes() -> list[str]:
    """The project's node modules (``pkg: dptpu``'s executables), found without importing them."""
    spec = importlib.util.find_spec(NODES_PACKAGE)
    locations = list(spec.submodule_search_locations or ()) if spec is not None else []
    return sorted(info.name for info in pkgutil.iter_modules(locations) if info.ispkg)


@dataclass
class NodeDraft:
    node: NodeLaunch
    display: str
    line: int


class NodeReader:
    """The ``node`` entries of a launch, read into :class:`NodeLaunch` drafts in the order they come."""

    def __init__(self, values: ValueReader, *, python: str, module_search_path: Sequence[str],
                 environ: Mapping[str, str]):
        self.values = values
        self.python = python
        self.module_search_path = list(module_search_path)
        self.environ = environ
        self.drafts: list[NodeDraft] = []

    def node_program_keys(self, body: MarkedDict) -> None:
        """Checks a skipped node's program keys need (the keys themselves were checked with the entry)."""
        if "exec" not in body:
            raise EntryFailure(body.line, "node: missing required key 'exec'")

    def program(self, scope: FileScope, body: MarkedDict, variables: dict[str, str]) \
            -> tuple[tuple[str, ...], str | None, str]:
        """The command that runs the node, its module (``None`` for a program) and its default label.

        ``pkg: dptpu`` with ``exec: NAME`` runs the project's node ``dptpu.nodes.NAME`` (``python -m``); another
        ``pkg`` is a Python package whose module ``exec`` runs (``python -m PKG.EXEC``); without ``pkg``, ``exec`` is
        a program (a path, or a name on ``PATH``), as launch_ros runs a node without a package.
        """
        executable = self.values.text(scope, body, "exec", "node", variables=variables).strip()
        line = body.value_line("exec")
        if "pkg" not in body:
            return (self.find_executable(scope, executable, line),), None, os.path.basename(executable)
        package = self.values.text(scope, body, "pkg", "node", variables=variables).strip()
        if not _NAME.fullmatch(executable):
            raise EntryFailure(line, f"node: exec {executable!r} of pkg {package!r} must be a module name "
                                     f"(letters, digits and _)")
        module = f"{NODES_PACKAGE}.{executable}" if package == PACKAGE_NAME else f"{package}.{executable}"
        problem = module_problem(module, self.module_search_path)
        if problem:
            if package == PACKAGE_NAME:
                problem = f"pkg {PACKAGE_NAME} has no node {executable!r}{suggest(executable, dptpu_nodes())} " \
                          f"(its nodes: {', '.join(dptpu_nodes())})"
            raise EntryFailure(line, f"node: {problem}")
        return (self.python, "-m", module), module, executable

    def node(self, scope: FileScope, body: MarkedDict, namespace: str, variables: dict[str, str]) -> None:
        self.node_program_keys(body)
        kind = "node"
        program, module, default_label = self.program(scope, body, variables)
        arguments = self.arguments(scope, body, variables) if "args" in body else ()
        name = None
        if "name" in body:
            name = self.values.text(scope, body, "name", kind, variables=variables).strip()
            if not _NAME.fullmatch(name):
                raise EntryFailure(body.value_line("name"),
                                   f"node: name {name!r} is not a valid node name: letters, digits "
                                   f"and _, not starting with a digit, no /")
        node_namespace = self.values.join_namespace(scope, body, namespace, variables, kind) or None
        parameters = tuple(self.parameters(scope, body, variables)) if "param" in body else ()
        remaps = tuple(self.remaps(scope, body, variables)) if "remap" in body else ()
        env = tuple(self.environment(scope, body, variables)) if "env" in body else ()
        respawn = self.values.boolean(scope, body, "respawn", kind, variables, False)
        required = self.on_exit(scope, body, variables)
        if respawn and required:
            raise EntryFailure(body.key_line("on_exit"),
                               "node: a node cannot have both on_exit: shutdown and respawn: true "
                               "(on_exit: shutdown stops everything when it exits; respawn restarts it)")
        delay = self.values.seconds(scope, body, "respawn_delay", kind, variables, 0.0)
        cap = self.values.seconds(scope, body, "respawn_max_delay", kind, variables,
                                  max(DEFAULT_RESPAWN_MAX_DELAY_S, delay))
        if cap < delay:
            raise EntryFailure(body.value_line("respawn_max_delay"), f"node: respawn_max_delay ({cap} s) must be >= "
                                                                     f"respawn_delay ({delay} s)")
        output = (self.values.text(scope, body, "output", kind, variables=variables).strip() if "output" in body
                  else "screen")
        if output not in OUTPUT_MODES:
            raise EntryFailure(body.value_line("output"), f"node: output must be one of {', '.join(OUTPUT_MODES)}; "
                                                          f"got {output!r}{suggest(output, OUTPUT_MODES)}")
        node = NodeLaunch(label=name or default_label, source=f"{scope.display}:{body.line}", program=program,
                          module=module, arguments=arguments, name=name, namespace=node_namespace,
                          parameters=parameters, remaps=remaps, env=env, respawn=respawn, respawn_delay_s=delay,
                          respawn_max_delay_s=cap, required=required, output=output)
        self.drafts.append(NodeDraft(node, scope.display, body.line))

    def on_exit(self, scope: FileScope, body: MarkedDict, variables) -> bool:
        """True for ``on_exit: shutdown`` (ROS 2's action when the process exits: stop the whole launch)."""
        if "on_exit" not in body:
            return False
        action = self.values.text(scope, body, "on_exit", "node", variables=variables).strip()
        if action != "shutdown":
            raise EntryFailure(body.value_line("on_exit"), f"node: on_exit supports only 'shutdown' (stop the launch "
                                                           f"when this node exits); got {action!r}")
        return True

    def find_executable(self, scope: FileScope, executable: str, line: int) -> str:
        if not executable:
            raise EntryFailure(line, "node: executable is empty")
        if os.sep in executable or (os.altsep and os.altsep in executable):
            path = os.path.normpath(os.path.join(scope.directory, os.path.expanduser(executable)))
            if not os.path.isfile(path):
                raise EntryFailure(line,
                                   f"node: executable {executable!r} not found (looked for {path}; a relative path "
                                   f"is relative to the launch file)")
            if not os.access(path, os.X_OK):
                raise EntryFailure(line, f"node: executable {path} is not executable (chmod +x it)")
            return path
        found = shutil.which(executable, path=self.environ.get("PATH", os.defpath))
        if found is None:
            raise EntryFailure(line, f"node: executable {executable!r} not found on PATH")
        return os.path.abspath(found)

    def arguments(self, scope: FileScope, body: MarkedDict, variables) -> tuple[str, ...]:
        value, line = body["args"], body.value_line("args")
        if isinstance(value, str):
            text = self.values.substitute(scope, value, variables, line, "node args")
            try:
                return tuple(shlex.split(text))
            except ValueError as exc:
                raise EntryFailure(line, f"node: args {text!r} cannot be split into words: {exc}") from None
        if isinstance(value, MarkedList):
            words = []
            for index, item in enumerate(value):
                if isinstance(item, list | dict) or item is None:
                    raise EntryFailure(value.item_line(index),
                                       f"node: each item of args must be text; got {type_name(item)}")
                if isinstance(item, str):
                    words.append(self.values.substitute(scope, item, variables, value.item_line(index), "node args"))
                else:
                    words.append(("true" if item else "false") if isinstance(item, bool) else str(item))
            return tuple(words)
        raise EntryFailure(line, f"node: args must be text or a list of words; got {type_name(value)}")

    def parameters(self, scope: FileScope, body: MarkedDict, variables, prefix: str = "", key: str = "param"):
        for item in self.values.list_of_mappings(body, key, "node"):
            self.values.check_keys("param", item, required=(), allowed=("name", "value", "param", "from"))
            if "from" in item:
                if len(item) > 1:
                    raise EntryFailure(item.line,
                                       "param: 'from' (a parameter file) stands alone; put 'name'/'value' in "
                                       "their own item")
                if prefix:
                    raise EntryFailure(item.line,
                                       "param: a parameter file ('from') cannot be nested under a parameter name")
                yield self.parameter_file(scope, item, variables)
                continue
            if "name" not in item:
                raise EntryFailure(item.line, "param: missing required key 'name' (or 'from' for a parameter file)")
            if ("value" in item) == ("param" in item):
                raise EntryFailure(item.line, "param: give exactly one of 'value' or nested 'param'")
            name = self.values.text(scope, item, "name", "param", variables=variables).strip()
            if not _PARAM_NAME.fullmatch(name):
                raise EntryFailure(item.value_line("name"), f"param: {name!r} is not a valid parameter name")
            full = f"{prefix}{name}"
            if "param" in item:
                yield from self.parameters(scope, item, variables, prefix=f"{full}.")
            else:
                yield InlineParameter(full, self.parameter_value(scope, item, variables, full))

    def parameter_value(self, scope: FileScope, item: MarkedDict, variables, name: str):
        value, line = item["value"], item.value_line("value")
        if isinstance(value, MarkedList):
            values = [self.parameter_scalar(scope, entry, variables, value.item_line(index), name)
                      for index, entry in enumerate(value)]
            kinds = {type(entry) for entry in values}
            if len(kinds) > 1:
                listing = " and ".join(sorted(kind.__name__ for kind in kinds))
                raise EntryFailure(line,
                                   f"param {name!r}: array items must all have one type (bool, int, float or str); "
                                   f"got {listing}")
            return values
        return self.parameter_scalar(scope, value, variables, line, name)

    def parameter_scalar(self, scope: FileScope, value, variables, line: int, name: str):
        if value is None:
            raise EntryFailure(line, f"param {name!r} has no value (write value: ...)")
        if isinstance(value, dict):
            raise EntryFailure(line, f"param {name!r}: a value cannot be a mapping; nest parameters with 'param:' "
                                     f"items instead")
        if isinstance(value, list):
            raise EntryFailure(line, f"param {name!r}: arrays cannot be nested")
        if isinstance(value, str) and has_substitution(value):
            text = self.values.substitute(scope, value, variables, line, f"param {name}")
            try:  # like ROS 2: text produced by a substitution is typed by YAML ("10" -> 10)
                typed = yaml.safe_load(text)
            except yaml.YAMLError:
                return text
            return typed if isinstance(typed, PARAMETER_SCALAR_TYPES) else text
        if not isinstance(value, PARAMETER_SCALAR_TYPES):
            raise EntryFailure(line,
                               f"param {name!r}: a value must be bool, int, float or text; got {type_name(value)} "
                               f"(quote it to make it text)")
        return value

    def parameter_file(self, scope: FileScope, item: MarkedDict, variables) -> ParameterFile:
        text = self.values.text(scope, item, "from", "param", variables=variables)
        line = item.value_line("from")
        path = os.path.normpath(os.path.join(scope.directory, os.path.expanduser(text)))
        if not os.path.isfile(path):
            raise EntryFailure(line, f"param: parameter file {text!r} not found (looked for {path}; a relative path is "
                                     f"relative to the launch file)")
        try:
            content = yaml.safe_load(Path(path).read_text(encoding="utf-8"))
        except (yaml.YAMLError, OSError, UnicodeDecodeError) as exc:
            raise EntryFailure(line, f"param: parameter file {text!r} cannot be read as YAML: "
                                     f"{str(exc).splitlines()[0]}") from None
        if not isinstance(content, dict) or not any(
                isinstance(section, dict) and "ros__parameters" in section for section in content.values()):
            raise EntryFailure(line, f"param: parameter file {text!r} is not a ROS 2 parameter file "
                                     f"(expected NODE_NAME: {{ros__parameters: {{...}}}}, or '/**:' for every node)")
        return ParameterFile(path)

    def remaps(self, scope: FileScope, body: MarkedDict, variables):
        for item in self.values.list_of_mappings(body, "remap", "node"):
            self.values.check_keys("remap", item, required=("from", "to"), allowed=("from", "to"))
            pair = []
            for key in ("from", "to"):
                text = self.values.text(scope, item, key, "remap", variables=variables).strip()
                if not text or ":=" in text or any(char.isspace() for char in text):
                    raise EntryFailure(item.value_line(key), f"remap: {key} must be a non-empty name without spaces "
                                                             f"or ':='; got {text!r}")
                pair.append(text)
            yield tuple(pair)

    def environment(self, scope: FileScope, body: MarkedDict, variables):
        for item in self.values.list_of_mappings(body, "env", "node"):
            self.values.check_keys("env", item, required=("name", "value"), allowed=("name", "value"))
            name = self.values.text(scope, item, "name", "env", variables=variables).strip()
            if not _ENV_NAME.fullmatch(name):
                raise EntryFailure(item.value_line("name"), f"env: {name!r} is not a valid environment variable name")
            yield name, self.values.text(scope, item, "value", "env", variables=variables)

    def finish_nodes(self, add: Callable[[str, int | None, str], None]) -> tuple[NodeLaunch, ...]:
        """Check node names are unique (``add(file, line, message)`` records a clash); make labels unique
        (``name``, then ``ns/name``, then ``-2``...)."""
        seen: dict[str, NodeDraft] = {}
        for draft in self.drafts:
            full = draft.node.full_name
            if full is None:
                continue
            if full in seen:
                first = seen[full]
                add(draft.display, draft.line, f"node: name {full!r} is used twice (first at "
                                               f"{first.node.source}); give each node its own name or namespace")
            else:
                seen[full] = draft
        original = [draft.node.label for draft in self.drafts]
        labels = list(original)
        for index, draft in enumerate(self.drafts):
            full_name = draft.node.full_name  # set when the node has a name
            if original.count(draft.node.label) > 1 and full_name is not None and draft.node.namespace:
                labels[index] = full_name.lstrip("/")
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
