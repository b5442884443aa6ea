"""Parameter messages and services with ROS 2 ``rcl_interfaces`` names and fields.

``ParameterDescriptor``, ``SetParametersResult``, ``FloatingPointRange`` and ``IntegerRange`` are what
node code uses (``from rcl_interfaces.msg import SetParametersResult`` in rclpy); the rest is the wire
form of the standard parameter services every node serves (``~/get_parameters`` ...).

One difference from ROS 2: the codec has no ``string[]`` field, so every ``string[]`` of ROS 2 is a
list of :class:`~dptpu.graph.interfaces.String` here (``names: list[String]``); :func:`strings` and
:func:`texts` convert. Node code never sees this: ``dptpu.graph.parameter_client`` takes and gives str.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from ..messages.schema import Message, message, nested, nested_list, scalar, sequence
from .interfaces import String, service_type

__all__ = [
    "ParameterType", "ParameterValue", "Parameter", "FloatingPointRange", "IntegerRange", "ParameterDescriptor",
    "SetParametersResult", "ListParametersResult", "GetParameters", "GetParameterTypes", "SetParameters",
    "SetParametersAtomically", "ListParameters", "DescribeParameters", "strings", "texts",
]


def strings(values: Iterable[object]) -> list[String]:
    """``["a", "b"]`` -> ``[String(data="a"), String(data="b")]`` (the wire form of ``string[]``)."""
    return [String(data=str(v)) for v in values]


def texts(values: Iterable[String]) -> list[str]:
    """Inverse of :func:`strings`."""
    return [v.data for v in values]


@message("rcl_interfaces/msg/ParameterType", version=1)
class ParameterType(Message):
    """Parameter type codes (constants only, as in ROS 2)."""

    PARAMETER_NOT_SET = 0
    PARAMETER_BOOL = 1
    PARAMETER_INTEGER = 2
    PARAMETER_DOUBLE = 3
    PARAMETER_STRING = 4
    PARAMETER_BYTE_ARRAY = 5
    PARAMETER_BOOL_ARRAY = 6
    PARAMETER_INTEGER_ARRAY = 7
    PARAMETER_DOUBLE_ARRAY = 8
    PARAMETER_STRING_ARRAY = 9


@message("rcl_interfaces/msg/ParameterValue", version=1)
class ParameterValue(Message):
    """A parameter value: ``type`` (ParameterType code) says which ``*_value`` field holds it."""

    type: int = scalar("uint8")
    bool_value: bool = scalar("bool")
    integer_value: int = scalar("int64")
    double_value: float = scalar("float64")
    string_value: str = scalar("string")
    byte_array_value: np.ndarray = sequence("uint8")
    bool_array_value: np.ndarray = sequence("bool")
    integer_array_value: np.ndarray = sequence("int64")
    double_array_value: np.ndarray = sequence("float64")
    string_array_value: list[String] = nested_list(String)


@message("rcl_interfaces/msg/Parameter", version=1)
class Parameter(Message):
    """A named parameter value (the wire form; node code uses :class:`dptpu.graph.Parameter`)."""

    name: str = scalar("string")
    value: ParameterValue = nested(ParameterValue)


@message("rcl_interfaces/msg/FloatingPointRange", version=1)
class FloatingPointRange(Message):
    """Allowed range of a DOUBLE parameter: ``from_value <= v <= to_value``; ``step`` 0 = continuous."""

    from_value: float = scalar("float64")
    to_value: float = scalar("float64")
    step: float = scalar("float64")


@message("rcl_interfaces/msg/IntegerRange", version=1)
class IntegerRange(Message):
    """Allowed range of an INTEGER parameter: ``from_value <= v <= to_value``; ``step`` 0 or 1 = any."""

    from_value: int = scalar("int64")
    to_value: int = scalar("int64")
    step: int = scalar("uint64")


@message("rcl_interfaces/msg/ParameterDescriptor", version=1)
class ParameterDescriptor(Message):
    """How a parameter may be set (rclpy: ``declare_parameter(name, value, descriptor)``).

    Attributes
    ----------
    name : str
    type : int
        ParameterType code; filled from the declared value when left 0.
    description, additional_constraints : str
        Free text shown by ``dptpu param describe``.
    read_only : bool
        Set only at declaration (overrides apply), never afterwards.
    dynamic_typing : bool
        Allow later values of another type.
    floating_point_range, integer_range : list
        At most one range each.
    """

    name: str = scalar("string")
    type: int = scalar("uint8")
    description: str = scalar("string")
    additional_constraints: str = scalar("string")
    read_only: bool = scalar("bool")
    dynamic_typing: bool = scalar("bool")
    floating_point_range: list[FloatingPointRange] = nested_list(FloatingPointRange)
    integer_range: list[IntegerRange] = nested_list(IntegerRange)


@message("rcl_interfaces/msg/SetParametersResult", version=1)
class SetParametersResult(Message):
    """Outcome of setting parameters: ``successful`` and, when not, a ``reason``."""

    successful: bool = scalar("bool")
    reason: str = scalar("string")


@message("rcl_interfaces/msg/ListParametersResult", version=1)
class ListParametersResult(Message):
    """Parameter names and the distinct dotted prefixes among them."""

    names: list[String] = nested_list(String)
    prefixes: list[String] = nested_list(String)


@service_type("rcl_interfaces/srv/GetParameters")
class GetParameters:
    class Request(Message):
        names: list[String] = nested_list(String)

    class Response(Message):
        values: list[ParameterValue] = nested_list(ParameterValue)


@service_type("rcl_interfaces/srv/GetParameterTypes")
class GetParameterTypes:
    class Request(Message):
        names: list[String] = nested_list(String)

    class Response(Message):
        types: np.ndarray = sequence("uint8")


@service_type("rcl_interfaces/srv/SetParameters")
class SetParameters:
    class Request(Message):
        parameters: list[Parameter] = nested_list(Parameter)

    class Response(Message):
        results: list[SetParametersResult] = nested_list(SetParametersResult)


@service_type("rcl_interfaces/srv/SetParametersAtomically")
class SetParametersAtomically:
    class Request(Message):
        parameters: list[Parameter] = nested_list(Parameter)

    class Response(Message):
        result: SetParametersResult = nested(SetParametersResult)


@service_type("rcl_interfaces/srv/ListParameters")
class ListParameters:
    DEPTH_RECURSIVE = 0

    class Request(Message):
        prefixes: list[String] = nested_list(String)
        depth: int = scalar("uint64")

    class Response(Message):
        result: ListParametersResult = nested(ListParametersResult)


@service_type("rcl_interfaces/srv/DescribeParameters")
class DescribeParameters:
    class Request(Message):
        names: list[String] = nested_list(String)

    class Response(Message):
        descriptors: list[ParameterDescriptor] = nested_list(ParameterDescriptor)
