"""The node graph runtime: rclpy's API over ZeroMQ + msgpack (``dptpu.messages``).

Use it as ``rclpy``::

    from dptpu import graph as rclpy            # or: import dptpu.graph as rclpy
    from dptpu.graph.node import Node
    from dptpu.graph.interfaces import String

    class Talker(Node):
        def __init__(self):
            super().__init__("talker")
            self.publisher = self.create_publisher(String, "chatter", 10)
            self.timer = self.create_timer(0.5, lambda: self.publisher.publish(String(data="hello")))

    rclpy.init(args=sys.argv)
    rclpy.spin(Talker())

Modules (one concept each): :mod:`.context` (init/ok/shutdown), :mod:`.node`, :mod:`.names`,
:mod:`.arguments` and :mod:`.param_files` (the ROS 2 command line and parameter files), :mod:`.qos`,
:mod:`.parameters`, :mod:`.executors`, :mod:`.callback_groups`, :mod:`.timer`, :mod:`.clock`,
:mod:`.logging`, :mod:`.exceptions`, :mod:`.publisher`, :mod:`.subscription`, :mod:`.services`,
:mod:`.task`, :mod:`.interfaces` and :mod:`.rcl_interfaces` (service and parameter types),
:mod:`.parameter_service`, :mod:`.parameter_client`, :mod:`.discovery` (announcements, graph
snapshots), :mod:`.transport` (sockets, endpoints, Curve), :mod:`.peers` (other hosts),
:mod:`.runtime` (the I/O thread), :mod:`.lease` (sockets lent to a waiting executor),
:mod:`.endpoint_matching` (which publishers and servers to connect to). Design and behaviour: ``docs/graph.md``.

Tools built on the runtime (launch, recording, introspection) live in :mod:`dptpu.tools`; the runtime imports only
:mod:`dptpu.messages`, never its scanner types.
"""

from __future__ import annotations

from .arguments import remove_ros_args
from .callback_groups import CallbackGroup, MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from .clock import Clock, ClockType, Duration, Time
from .context import Context, get_default_context, init, ok, shutdown, try_shutdown
from .exceptions import (
    ExternalShutdownException,
    GraphError,
    InvalidNamespaceException,
    InvalidNodeNameException,
    InvalidParameterTypeException,
    InvalidParameterValueException,
    InvalidQoSProfileException,
    InvalidServiceNameException,
    InvalidTopicNameException,
    NotInitializedException,
    ParameterAlreadyDeclaredException,
    ParameterException,
    ParameterImmutableException,
    ParameterNotDeclaredException,
    ParameterUninitializedException,
    ROSArgumentsError,
    ServiceCallError,
    UnknownROSArgsError,
)
from .executors import Executor, MultiThreadedExecutor, SingleThreadedExecutor
from .interfaces import Empty, SetBool, String, Trigger, lookup_service, service_type
from .logging import LoggingSeverity, get_logger
from .node import Node
from .parameter_client import AsyncParameterClient
from .parameters import Parameter
from .qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
    qos_profile_default,
    qos_profile_parameter_events,
    qos_profile_parameters,
    qos_profile_sensor_data,
    qos_profile_services_default,
    qos_profile_system_default,
)
from .rcl_interfaces import FloatingPointRange, IntegerRange, ParameterDescriptor, SetParametersResult
from .task import Future, Task

__all__ = [
    # lifecycle
    "init", "shutdown", "try_shutdown", "ok", "Context", "get_default_context",
    "create_node", "spin", "spin_once", "spin_until_future_complete", "get_global_executor", "remove_ros_args",
    # nodes and entities
    "Node", "Parameter", "ParameterDescriptor", "SetParametersResult", "FloatingPointRange", "IntegerRange",
    "AsyncParameterClient", "Future", "Task",
    # executors
    "Executor", "SingleThreadedExecutor", "MultiThreadedExecutor", "CallbackGroup",
    "MutuallyExclusiveCallbackGroup", "ReentrantCallbackGroup",
    # QoS
    "QoSProfile", "HistoryPolicy", "ReliabilityPolicy", "DurabilityPolicy", "qos_profile_default",
    "qos_profile_system_default", "qos_profile_sensor_data", "qos_profile_services_default",
    "qos_profile_parameters", "qos_profile_parameter_events",
    # time, logging
    "Clock", "ClockType", "Time", "Duration", "get_logger", "LoggingSeverity",
    # interfaces
    "String", "Empty", "Trigger", "SetBool", "service_type", "lookup_service",
    # errors
    "GraphError", "NotInitializedException", "ExternalShutdownException", "InvalidNodeNameException",
    "InvalidNamespaceException", "InvalidTopicNameException", "InvalidServiceNameException",
    "ROSArgumentsError", "UnknownROSArgsError", "InvalidQoSProfileException", "ParameterException",
    "ParameterNotDeclaredException", "ParameterAlreadyDeclaredException", "InvalidParameterValueException",
    "InvalidParameterTypeException", "ParameterImmutableException", "ParameterUninitializedException",
    "ServiceCallError",
]

_global_executor = None


def get_global_executor() -> SingleThreadedExecutor:
    """The executor ``spin``/``spin_once`` use when given none (one per process, of the default context)."""
    global _global_executor
    if _global_executor is None or _global_executor._is_shutdown \
            or _global_executor.context is not get_default_context():
        _global_executor = SingleThreadedExecutor()
    return _global_executor


def create_node(node_name, *, context=None, cli_args=None, namespace=None, use_global_arguments=True,
                enable_rosout=True, start_parameter_services=True, parameter_overrides=None,
                allow_undeclared_parameters=False, automatically_declare_parameters_from_overrides=False) -> Node:
    """A new :class:`Node` (same arguments)."""
    return Node(node_name, context=context, cli_args=cli_args, namespace=namespace,
                use_global_arguments=use_global_arguments, enable_rosout=enable_rosout,
                start_parameter_services=start_parameter_services, parameter_overrides=parameter_overrides,
                allow_undeclared_parameters=allow_undeclared_parameters,
                automatically_declare_parameters_from_overrides=automatically_declare_parameters_from_overrides)


def _executor_for(node, executor):
    return executor if executor is not None else (
        node.executor if node.executor is not None else get_global_executor())


def spin(node, executor=None) -> None:
    """Run ``node``'s callbacks until its context shuts down (Ctrl-C raises KeyboardInterrupt)."""
    executor = _executor_for(node, executor)
    added = executor.add_node(node)
    try:
        executor.spin()
    finally:
        if added:
            executor.remove_node(node)


def spin_once(node, *, executor=None, timeout_sec=None) -> None:
    """Run at most one of ``node``'s callbacks, waiting up to ``timeout_sec``."""
    executor = _executor_for(node, executor)
    added = executor.add_node(node)
    try:
        executor.spin_once(timeout_sec=timeout_sec)
    finally:
        if added:
            executor.remove_node(node)


def spin_until_future_complete(node, future, executor=None, timeout_sec=None) -> None:
    """Run ``node``'s callbacks until ``future`` is done or ``timeout_sec`` passes."""
    executor = _executor_for(node, executor)
    added = executor.add_node(node)
    try:
        executor.spin_until_future_complete(future, timeout_sec=timeout_sec)
    finally:
        if added:
            executor.remove_node(node)
