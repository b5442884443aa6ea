"""Parameter values as the ``ros2 param`` CLI reads and prints them.

- :func:`parse_parameter_value`: the command line's value is YAML, so ``5`` is an INTEGER, ``5.0`` a
  DOUBLE, ``true`` a BOOL, ``[1, 2]`` an INTEGER_ARRAY and ``hello`` a STRING (``ros2 param set``).
  One difference: PyYAML follows YAML 1.1, where ``1e-3`` (no dot) is a string; here an unquoted
  number in exponent form is a DOUBLE, as YAML 1.2 says (``ros2 param set`` would send a STRING).
- :func:`format_parameter_value`: ``ros2 param get``'s line, e.g. ``Integer value is: 5``.
- :func:`parameters_yaml`: ``ros2 param dump``'s YAML, ``/node: {ros__parameters: {...}}``, dotted
  names nested (``nested.x`` -> ``nested: {x: ...}``), keys sorted.
"""

from __future__ import annotations

import re

import yaml

from dptpu.graph.parameters import Parameter

__all__ = ["parse_parameter_value", "format_parameter_value", "parameters_yaml"]

# YAML 1.2 core-schema float without a dot, e.g. 1e-3 or -2E+5 (YAML 1.1 makes these strings).
_EXPONENT_FLOAT = re.compile(r"^[-+]?[0-9]+[eE][-+]?[0-9]+$")

_LABELS = {
    Parameter.Type.BOOL: "Boolean value is:",
    Parameter.Type.INTEGER: "Integer value is:",
    Parameter.Type.DOUBLE: "Double value is:",
    Parameter.Type.STRING: "String value is:",
    Parameter.Type.BYTE_ARRAY: "Byte values are:",
    Parameter.Type.BOOL_ARRAY: "Boolean values are:",
    Parameter.Type.INTEGER_ARRAY: "Integer values are:",
    Parameter.Type.DOUBLE_ARRAY: "Double values are:",
    Parameter.Type.STRING_ARRAY: "String values are:",
}


def parse_parameter_value(text: str):
    """The parameter value written as YAML in ``text``.

    Returns
    -------
    bool, int, float, str or list
        A list holds values of one type (an empty list is an empty array).

    Raises
    ------
    ValueError
        Invalid YAML, ``null``, a mapping, or a list mixing types; the message says what to write.
    """
    if not isinstance(text, str):
        raise ValueError(f"parameter value must be text; got {type(text).__name__}")
    try:
        value = yaml.safe_load(text)
    except yaml.YAMLError:
        raise ValueError(f"parameter value is not valid YAML: {text!r}; quote strings that contain ':' or '#'") \
            from None
    if isinstance(value, str) and _EXPONENT_FLOAT.match(text.strip()):
        value = float(value)
    if value is None:
        raise ValueError(f"parameter value must not be empty or null; got {text!r} (write '\"\"' for an empty string)")
    if isinstance(value, dict):
        raise ValueError(f"parameter value must be a scalar or a list, not a mapping; got {text!r}")
    try:
        Parameter("value", value=value)  # checks the type: one of the parameter types, lists of one type
    except ValueError as exc:
        raise ValueError(f"parameter value {text!r} has no parameter type: {exc}") from None
    return value


def format_parameter_value(parameter_type: Parameter.Type, value, *, hide_type: bool = False) -> str:
    """``ros2 param get``'s output line for a value of ``parameter_type``.

    ``Parameter not set.`` for NOT_SET; ``hide_type=True`` prints only the value.
    """
    parameter_type = Parameter.Type(parameter_type)
    if parameter_type == Parameter.Type.NOT_SET:
        return "Parameter not set."
    if parameter_type == Parameter.Type.BYTE_ARRAY:
        value = list(value)
    text = str(value)
    return text if hide_type else f"{_LABELS[parameter_type]} {text}"


def _nest(values: dict) -> dict:
    tree: dict = {}
    for name in sorted(values):
        node = tree
        dotted = False
        *parents, leaf = name.split(".")
        for part in parents:
            child = node.setdefault(part, {})
            if not isinstance(child, dict):  # both "a" and "a.b" are parameters: keep the dotted name
                dotted = True
                break
            node = child
        value = values[name]
        if isinstance(value, bytes):
            value = list(value)
        if dotted:
            tree[name] = value
        else:
            node[leaf] = value
    return tree


def parameters_yaml(node_name: str, values: dict) -> str:
    """``ros2 param dump``'s YAML of ``{parameter name: value}`` of node ``node_name`` (fully qualified).

    Values that are None (NOT_SET) are left out, as ROS 2 does.
    """
    if not isinstance(node_name, str) or not node_name.startswith("/"):
        raise ValueError(f"node_name must be a fully qualified name starting with '/'; got {node_name!r}")
    kept = {name: value for name, value in values.items() if value is not None}
    document = {node_name: {"ros__parameters": _nest(kept)}}
    return yaml.safe_dump(document, default_flow_style=False, sort_keys=True, allow_unicode=True)
