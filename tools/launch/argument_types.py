"""The type of a launch argument, known from its default, and the check of a value given for it.

ROS 2 launch YAML declares no argument types, but a node parameter is statically typed (rclpy refuses ``2`` for a
DOUBLE parameter) and a value reaches it as YAML text (``frame_rate:=2`` becomes the integer 2). So a value given
on the command line or by an include is checked against the YAML type of the argument's default before anything
starts: a default of ``"0.0"`` makes a float argument that refuses ``2`` (write ``2.0``), ``"0"`` an integer one,
``"true"`` a boolean one. A default that is text (``mf``, ``640x480``, ``""``) or absent types nothing.
"""
from __future__ import annotations

import re

__all__ = ["argument_type", "argument_type_problem"]

_INT = re.compile(r"[-+]?[0-9]+")
_FLOAT = re.compile(r"[-+]?(\.[0-9]+|[0-9]+(\.[0-9]*)?)([eE][-+]?[0-9]+)?|[-+]?\.(inf|Inf|INF)|\.(nan|NaN|NAN)")
_BOOL = ("true", "false", "True", "False", "TRUE", "FALSE")


def argument_type(text: str) -> str | None:
    """The YAML scalar type of ``text``: ``"integer"``, ``"float"``, ``"boolean"`` or None (text).

    Convention: YAML 1.2's core schema, as ROS 2 reads parameter values (``1`` integer, ``1.0`` and ``1e3`` float,
    ``true`` boolean).
    """
    text = text.strip()
    if _INT.fullmatch(text):
        return "integer"
    if _FLOAT.fullmatch(text):
        return "float"
    if text in _BOOL:
        return "boolean"
    return None


def argument_type_problem(name: str, default: str | None, value: str) -> str | None:
    """Why ``value`` does not fit the type of argument ``name`` (the type of ``default``); None when it does."""
    expected = argument_type(default) if default is not None else None
    if expected is None:
        return None
    actual = argument_type(value)
    if actual == expected:
        return None
    hint = ""
    if expected == "float" and actual == "integer":
        hint = f": write {value.strip()}.0"
    elif expected == "boolean":
        hint = ": write true or false"
    return f"arg {name!r} is {'an' if expected == 'integer' else 'a'} {expected} (its default is {default!r}); " \
           f"got {value!r}{hint}"
