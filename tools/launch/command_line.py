"""The ROS 2 command line of a launched node: ``--ros-args`` with names, parameters and remappings.

For a node with name ``phase``, namespace ``/scanner``, parameters ``[min_modulation: 5.0, from:
params.yaml]`` and remapping ``/camera/image_raw -> /sim/image`` the tail is built in launch_ros's order
(name, namespace, parameters in the order written, remappings)::

    --ros-args -r __node:=phase -r __ns:=/scanner -p min_modulation:=5.0 --params-file /abs/params.yaml
               -r /camera/image_raw:=/sim/image

Inline parameter values are YAML-encoded (flow style, one line) so that the node, which parses the
text after ``:=`` as YAML, gets back the same value and type: ``5.0`` stays a float, the string
``"10"`` is sent as ``'10'``, a list as ``[1, 2, 3]``. Later parameters override earlier ones.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import yaml

__all__ = ["InlineParameter", "ParameterFile", "encode_parameter_value", "ros_arguments", "PARAMETER_SCALAR_TYPES"]

#: Python types a ROS 2 parameter value (or each item of an array parameter) may have.
PARAMETER_SCALAR_TYPES = (bool, int, float, str)


@dataclass(frozen=True)
class InlineParameter:
    """One ``-p NAME:=VALUE``: ``name`` dotted for nested parameters (``camera.exposure_us``)."""

    name: str
    value: object  # bool, int, float, str or a list of one of them


@dataclass(frozen=True)
class ParameterFile:
    """One ``--params-file PATH``: an absolute path to a ROS 2 parameter YAML file."""

    path: str


def _scalar_text(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return ".nan"
        if math.isinf(value):
            return ".inf" if value > 0 else "-.inf"
        text = repr(value)  # shortest round-trip form, e.g. 5.0, 1e-05
        if "e" in text and "." not in text.split("e")[0]:
            mantissa, exponent = text.split("e")
            text = f"{mantissa}.0e{exponent}"  # YAML 1.1 floats need a dot: 1.0e-05
        return text
    if isinstance(value, str):
        if value.isprintable():
            style = None
        else:  # newlines, tabs, control characters: one double-quoted line with escapes
            style = '"'
        text = yaml.safe_dump(value, default_style=style, default_flow_style=True, width=2 ** 31 - 1,
                              allow_unicode=True)
        text = text.removesuffix("\n...\n").removesuffix("\n")
        return text
    raise TypeError(f"not a parameter scalar: {type(value).__name__}")


def _double_quoted(text: str) -> str:
    dumped = yaml.safe_dump(text, default_style='"', width=2 ** 31 - 1, allow_unicode=True)
    return dumped.removesuffix("\n...\n").removesuffix("\n")


def encode_parameter_value(value) -> str:
    """The text after ``:=`` in ``-p NAME:=VALUE`` that YAML-decodes to ``value``, on one line.

    Parameters
    ----------
    value : bool, int, float, str, or list of one of these types
        A ROS 2 parameter value (arrays are homogeneous).

    Returns
    -------
    str
        Flow-style YAML, e.g. ``5.0``, ``true``, ``hello``, ``'10'``, ``[1, 2, 3]``, ``["a", "true"]``.

    Raises
    ------
    ValueError
        ``value`` is ``None``, a mapping, a nested list or any other type a parameter cannot have.
    """
    if isinstance(value, list | tuple):
        if any(isinstance(item, list | tuple | dict) or item is None for item in value):
            raise ValueError(f"a parameter array holds bool, int, float or str items; got {list(value)!r}")
        # Inside a flow sequence ',', '[', ']', '{', '}' end a plain scalar: strings there are double-quoted.
        return "[" + ", ".join(_double_quoted(item) if isinstance(item, str) else encode_parameter_value(item)
                               for item in value) + "]"
    if not isinstance(value, PARAMETER_SCALAR_TYPES):
        raise ValueError(f"a parameter value must be bool, int, float, str or a list of them; "
                         f"got {type(value).__name__} {value!r}")
    return _scalar_text(value)


def ros_arguments(*, name: str | None = None, namespace: str | None = None,
                  parameters: tuple | list = (), remaps: tuple | list = ()) -> list[str]:
    """The ``--ros-args ...`` tail of a node's command line, in launch_ros's order.

    Parameters
    ----------
    name : str, optional
        Node name; adds ``-r __node:=NAME``.
    namespace : str, optional
        Absolute namespace; adds ``-r __ns:=NAMESPACE``.
    parameters : sequence of InlineParameter or ParameterFile
        In order: ``-p NAME:=VALUE`` or ``--params-file PATH``; later entries override earlier ones.
    remaps : sequence of (str, str)
        ``(from, to)`` pairs; each adds ``-r FROM:=TO``.

    Returns
    -------
    list of str
        Always starts with ``--ros-args`` (launch_ros adds it even when nothing follows).
    """
    arguments = ["--ros-args"]
    if name:
        arguments += ["-r", f"__node:={name}"]
    if namespace:
        arguments += ["-r", f"__ns:={namespace}"]
    for parameter in parameters:
        if isinstance(parameter, InlineParameter):
            arguments += ["-p", f"{parameter.name}:={encode_parameter_value(parameter.value)}"]
        elif isinstance(parameter, ParameterFile):
            arguments += ["--params-file", parameter.path]
        else:
            raise ValueError(f"parameters must be InlineParameter or ParameterFile; got {parameter!r}")
    for source, target in remaps:
        arguments += ["-r", f"{source}:={target}"]
    return arguments
