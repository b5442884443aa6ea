"""ROS 2 parameter files and ``-p name:=value`` assignments, resolved into per-node overrides.

A parameters file is YAML shaped like ROS 2's::

    /**:                          # every node
      ros__parameters:
        frame_id: scanner_optical_frame
    phase_node:                   # the node named phase_node (any leading '/' optional)
      ros__parameters:
        steps: 12
        filter: {sigma_px: 1.5}   # nested maps become dotted names: filter.sigma_px
    /scanner/unwrap:              # fully qualified name
      ros__parameters: {method: nt}
    scanner:                      # nested namespace form: the node /scanner/cloud
      cloud:
        ros__parameters: {min_modulation: 0.1}

Node keys may use ``*`` (exactly one name token) and ``**`` (any number of tokens).
Within one file the wildcard entries apply first, then the exact ones, each in file order; across
sources (files and ``-p``) the later source wins. ``-p`` assignments apply to every node of the process.

Values must be bool, int, float, str, or a list of one of those types (no mixed lists, no maps).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import yaml

from .exceptions import ROSArgumentsError

__all__ = ["ParameterSource", "read_params_file", "parse_params_yaml", "parse_param_assignment",
           "node_pattern_matches", "overrides_for_node", "PARAMS_KEY"]

PARAMS_KEY = "ros__parameters"


@dataclass(frozen=True)
class ParameterSource:
    """One source of parameter overrides.

    Attributes
    ----------
    origin : str
        Where it came from, for error messages: a file path or ``-p name:=value``.
    entries : tuple of (str, dict)
        ``(node_pattern, {parameter_name: value})`` in application order; patterns are absolute,
        e.g. ``"/**"``, ``"/phase_node"``, ``"/scanner/*"``.
    """

    origin: str
    entries: tuple


def _check_value(value, where: str):
    scalar_types = (bool, int, float, str)
    if isinstance(value, scalar_types):
        return value
    if isinstance(value, list):
        kinds = {bool if isinstance(v, bool) else type(v) for v in value}
        if not all(isinstance(v, scalar_types) for v in value):
            raise ROSArgumentsError(f"{where}: list items must be bool, int, float or str; got {value!r}")
        if len(kinds) > 1:
            raise ROSArgumentsError(f"{where}: list items must all have one type (write 1.0 for a float); "
                                    f"got {sorted(k.__name__ for k in kinds)} in {value!r}")
        return list(value)
    raise ROSArgumentsError(f"{where}: a parameter value must be bool, int, float, str or a list of them; "
                            f"got {type(value).__name__} {value!r}")


def _flatten(params, prefix: str, where: str, out: dict) -> None:
    if not isinstance(params, dict):
        raise ROSArgumentsError(f"{where}: '{PARAMS_KEY}' must hold a mapping of names to values; got "
                                f"{type(params).__name__}")
    for key, value in params.items():
        if not isinstance(key, str) or not key:
            raise ROSArgumentsError(f"{where}: parameter names must be non-empty strings; got {key!r}")
        name = f"{prefix}.{key}" if prefix else key
        if isinstance(value, dict):
            _flatten(value, name, where, out)
        else:
            out[name] = _check_value(value, f"{where}: parameter {name!r}")


def parse_params_yaml(data, origin: str = "<yaml>") -> ParameterSource:
    """Turn a loaded ROS 2 parameters document (a dict) into a :class:`ParameterSource`.

    Raises
    ------
    ROSArgumentsError
        When the document is not a mapping, a node entry lacks ``ros__parameters``, or a value has an
        unsupported type; the message names the origin and the key.
    """
    if not isinstance(data, dict):
        raise ROSArgumentsError(f"{origin}: a parameters file must be a mapping of node names to "
                                f"{{{PARAMS_KEY}: ...}}; got {type(data).__name__}")
    wildcard: list[tuple[str, dict]] = []
    exact: list[tuple[str, dict]] = []

    def walk(mapping: dict, tokens: list[str]) -> None:
        for key, value in mapping.items():
            if not isinstance(key, str) or not key.strip("/"):
                raise ROSArgumentsError(f"{origin}: node keys must be names like 'talker' or '/ns/talker'; "
                                        f"got {key!r}")
            if key == PARAMS_KEY:
                raise ROSArgumentsError(f"{origin}: '{PARAMS_KEY}' must be under a node name, e.g. "
                                        f"'talker: {{{PARAMS_KEY}: ...}}' or '/**: {{{PARAMS_KEY}: ...}}'")
            path = tokens + [t for t in key.split("/") if t]
            if not isinstance(value, dict):
                raise ROSArgumentsError(f"{origin}: node entry {'/' + '/'.join(path)!r} must be a mapping with "
                                        f"'{PARAMS_KEY}'; got {type(value).__name__}")
            if PARAMS_KEY in value:
                pattern = "/" + "/".join(path)
                params: dict = {}
                _flatten(value[PARAMS_KEY], "", f"{origin}: {pattern}", params)
                (wildcard if "*" in pattern else exact).append((pattern, params))
            rest = {k: v for k, v in value.items() if k != PARAMS_KEY}
            if rest:
                walk(rest, path)
            elif PARAMS_KEY not in value:
                raise ROSArgumentsError(f"{origin}: node entry {'/' + '/'.join(path)!r} has no '{PARAMS_KEY}'")

    walk(data, [])
    return ParameterSource(origin, tuple(wildcard + exact))


def read_params_file(path) -> ParameterSource:
    """Read a ROS 2 parameters YAML file; errors name the file (and YAML line for syntax errors)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ROSArgumentsError(f"cannot read parameters file {str(path)!r}: {exc.strerror or exc}") from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ROSArgumentsError(f"parameters file {str(path)!r} is not valid YAML: {exc}") from None
    if data is None:
        return ParameterSource(str(path), ())
    return parse_params_yaml(data, str(path))


def parse_param_assignment(text: str) -> ParameterSource:
    """``"name:=value"`` (value parsed as YAML; text that YAML cannot type stays a string)."""
    name, sep, raw = text.partition(":=")
    if not sep or not name:
        raise ROSArgumentsError(f"parameter assignment must look like 'name:=value'; got {text!r}")
    if raw == "":
        value = ""
    else:
        try:
            value = yaml.safe_load(raw)
        except yaml.YAMLError:
            value = raw
        if value is None or not isinstance(value, (bool, int, float, str, list)):
            value = raw
    value = _check_value(value, f"-p {text}")
    return ParameterSource(f"-p {text}", (("/**", {name: value}),))


def _pattern_regex(pattern: str) -> re.Pattern:
    parts = []
    for token in pattern.strip("/").split("/"):
        if token == "**":
            parts.append(r"(?:/[^/]+)*")
        else:
            parts.append("/" + "[^/]*".join(re.escape(piece) for piece in token.split("*")))
    return re.compile("^" + "".join(parts) + "$")


def node_pattern_matches(pattern: str, fully_qualified_node_name: str) -> bool:
    """Whether a parameters-file node key matches a node, e.g. ``("/**", "/a/b") -> True``."""
    if pattern in ("/**", "/*/**", "**"):
        return True
    return bool(_pattern_regex(pattern).match(fully_qualified_node_name))


def overrides_for_node(sources, fully_qualified_node_name: str) -> dict:
    """``{name: (value, origin)}``: every source's entries that match the node, later ones winning."""
    result: dict = {}
    for source in sources:
        for pattern, params in source.entries:
            if node_pattern_matches(pattern, fully_qualified_node_name):
                for name, value in params.items():
                    result[name] = (value, source.origin)
    return result
