"""The runtime's error family: every error it raises on purpose derives from :class:`GraphError`.

Names follow ``rclpy.exceptions`` so ``except`` clauses port unchanged. Errors caused by bad input
(a malformed name, an unknown command-line flag, a parameter of the wrong type) also derive from
``ValueError``; errors of state (using a context that is not initialized) from ``RuntimeError``.
"""

from __future__ import annotations

__all__ = [
    "GraphError",
    "NotInitializedException",
    "ExternalShutdownException",
    "InvalidNameException",
    "InvalidNodeNameException",
    "InvalidNamespaceException",
    "InvalidTopicNameException",
    "InvalidServiceNameException",
    "ROSArgumentsError",
    "UnknownROSArgsError",
    "InvalidQoSProfileException",
    "ParameterException",
    "ParameterNotDeclaredException",
    "ParameterAlreadyDeclaredException",
    "InvalidParameterException",
    "InvalidParameterValueException",
    "InvalidParameterTypeException",
    "ParameterImmutableException",
    "ParameterUninitializedException",
    "ServiceCallError",
]


class GraphError(Exception):
    """Base class of every error the graph runtime raises on purpose."""


class NotInitializedException(GraphError, RuntimeError):
    """The context was not initialized with ``init()``, or was shut down already."""

    def __init__(self, message: str = "dptpu.graph.init() has not been called, or the context was shut down"):
        super().__init__(message)


class ExternalShutdownException(GraphError):
    """The context was shut down while something waited on it (rclpy's name)."""


class InvalidNameException(GraphError, ValueError):
    """A node name, namespace, topic or service name breaks the ROS 2 naming rules."""

    def __init__(self, kind: str, name, reason: str):
        self.kind, self.name, self.reason = kind, name, reason
        super().__init__(f"invalid {kind} {name!r}: {reason}")


class InvalidNodeNameException(InvalidNameException):
    def __init__(self, name, reason: str):
        super().__init__("node name", name, reason)


class InvalidNamespaceException(InvalidNameException):
    def __init__(self, name, reason: str):
        super().__init__("namespace", name, reason)


class InvalidTopicNameException(InvalidNameException):
    def __init__(self, name, reason: str):
        super().__init__("topic name", name, reason)


class InvalidServiceNameException(InvalidNameException):
    def __init__(self, name, reason: str):
        super().__init__("service name", name, reason)


class ROSArgumentsError(GraphError, ValueError):
    """A ROS 2 command-line argument (after ``--ros-args``) is malformed."""


class UnknownROSArgsError(ROSArgumentsError):
    """A flag after ``--ros-args`` that this runtime does not know (rclpy's name)."""


class InvalidQoSProfileException(GraphError, ValueError):
    """A QoS profile or one of its policies is not valid."""


class ParameterException(GraphError, ValueError):
    """Base class of the parameter errors.

    Attributes
    ----------
    parameters : tuple
        The parameter name(s) or object(s) concerned.
    """

    def __init__(self, message: str, *parameters):
        self.parameters = parameters
        super().__init__(message)


class ParameterNotDeclaredException(ParameterException):
    """Getting or setting a parameter that was never declared (and undeclared ones are not allowed)."""

    def __init__(self, name):
        super().__init__(f"parameter {name!r} has not been declared (declare it with node.declare_parameter "
                         "or create the node with allow_undeclared_parameters=True)", name)


class ParameterAlreadyDeclaredException(ParameterException):
    def __init__(self, name):
        super().__init__(f"parameter {name!r} has already been declared", name)


class InvalidParameterException(ParameterException):
    """A parameter name is not valid."""

    def __init__(self, name, reason: str = "names are dot-separated tokens of letters, digits and '_'"):
        super().__init__(f"invalid parameter name {name!r}: {reason}", name)


class InvalidParameterValueException(ParameterException):
    """A value is outside its descriptor's range, or rejected by a callback at declaration."""

    def __init__(self, name, value, reason: str):
        super().__init__(f"invalid value {value!r} for parameter {name!r}: {reason}", name)


class InvalidParameterTypeException(ParameterException):
    """A value's type differs from the parameter's declared type (and dynamic typing is off)."""

    def __init__(self, name, reason: str):
        super().__init__(f"wrong type for parameter {name!r}: {reason}", name)


class ParameterImmutableException(ParameterException):
    """Setting a read-only parameter."""

    def __init__(self, name):
        super().__init__(f"parameter {name!r} is read-only", name)


class ParameterUninitializedException(ParameterException):
    """Reading a statically typed parameter that was declared without a value and got none."""

    def __init__(self, name):
        super().__init__(f"parameter {name!r} was declared with a type but no value, and no override "
                         "gave it one", name)


class ServiceCallError(GraphError, RuntimeError):
    """The server answered a request with an error (its callback raised, or it could not decode)."""
