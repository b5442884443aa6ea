"""The :class:`Node`: a named participant that owns publishers, subscriptions, timers, services and parameters.

Same constructor and methods as ``rclpy.node.Node`` (the ones listed in ``docs/graph.md``); a node
written against this class runs on rclpy by changing imports. The work is done elsewhere:
names in :mod:`.names`, parameters in :mod:`.parameters`, sockets in :mod:`.publisher`,
:mod:`.subscription`, :mod:`.services`, scheduling in :mod:`.executors`.
"""

from __future__ import annotations

import threading
import time
import uuid
import weakref
from dataclasses import replace
from typing import TYPE_CHECKING

from ..messages.registry import is_registered
from ..messages.schema import Message
from .arguments import RosArguments, parse_ros_arguments
from .callback_groups import MutuallyExclusiveCallbackGroup
from .clock import ROSClock
from .context import get_default_context
from .discovery import snapshot_from_entries
from .exceptions import NotInitializedException
from .interfaces import is_service_type
from .known_publishers import KnownPublishers
from .logging import get_logger, set_logger_level
from .names import (
    expand_topic_name,
    fully_qualified_name,
    logger_name_of,
    normalize_namespace,
    remap_name,
    remap_namespace,
    remap_node_name,
    validate_node_name,
)
from .param_files import overrides_for_node
from .parameter_service import ParameterService
from .parameters import NodeParameters, Parameter
from .publisher import Publisher
from .qos import as_qos_profile, qos_profile_services_default
from .services import Client, Service
from .subscription import Subscription
from .timer import Rate, Timer

if TYPE_CHECKING:  # for annotations only
    from .executors import Executor

__all__ = ["Node"]


def _check_message_type(msg_type, what: str) -> None:
    if not (isinstance(msg_type, type) and issubclass(msg_type, Message)
            and is_registered(getattr(msg_type, "TYPE_NAME", None))):
        raise ValueError(f"{what} needs a registered message class (e.g. dptpu.messages.Image); got {msg_type!r}")


def _check_service_type(srv_type, what: str) -> None:
    if not is_service_type(srv_type):
        raise ValueError(f"{what} needs a service type made with dptpu.graph.interfaces.service_type "
                         f"(e.g. dptpu.graph.interfaces.Trigger); got {srv_type!r}")


class Node:
    """A node of the graph.

    Parameters
    ----------
    node_name : str
        Letters, digits and ``_``; may be changed by a ``__node:=`` remapping.
    context : Context, optional
        Default: the default context (``dptpu.graph.init()``).
    cli_args : list of str, optional
        This node's own ROS arguments, e.g. ``["--ros-args", "-r", "image:=/camera/image_raw"]``;
        they take precedence over the context's (``init(args=...)``).
    namespace : str, optional
        ``"/scanner"`` or ``"scanner"``; default ``"/"``.
    use_global_arguments : bool
        Whether the context's ROS arguments apply too.
    enable_rosout : bool
        Accepted for compatibility; there is no /rosout topic.
    start_parameter_services : bool
        Serve ``~/get_parameters``, ``~/set_parameters``, ``~/set_parameters_atomically``,
        ``~/list_parameters``, ``~/describe_parameters``, ``~/get_parameter_types``.
    parameter_overrides : list of Parameter, optional
        Initial values that beat the command line and files.
    allow_undeclared_parameters : bool
    automatically_declare_parameters_from_overrides : bool
        Declare every parameter an override names.

    Raises
    ------
    NotInitializedException
        The context is not initialized.
    InvalidNodeNameException, InvalidNamespaceException
        A bad name or namespace (after remapping).
    """

    def __init__(self, node_name, *, context=None, cli_args=None, namespace=None, use_global_arguments=True,
                 enable_rosout=True, start_parameter_services=True, parameter_overrides=None,
                 allow_undeclared_parameters=False, automatically_declare_parameters_from_overrides=False) -> None:
        self._context = context if context is not None else get_default_context()
        if not self._context.ok():
            raise NotInitializedException()
        validate_node_name(node_name)
        node_args = parse_ros_arguments(cli_args if cli_args is not None else [])
        global_args = self._context._arguments if use_global_arguments else RosArguments()
        self._remap_rules = list(node_args.remap_rules) + list(global_args.remap_rules)
        self._original_name = node_name
        self._name = validate_node_name(remap_node_name(self._remap_rules, node_name))
        self._namespace = remap_namespace(self._remap_rules, node_name, normalize_namespace(namespace))
        self._fqn = fully_qualified_name(self._namespace, self._name)
        self._gid = uuid.uuid4().hex
        self._start_time = time.time()
        for args in (global_args, node_args):
            for logger_name, level in args.log_levels.items():
                set_logger_level(logger_name, level)
        self._logger = get_logger(logger_name_of(self._namespace, self._name))
        self._clock = ROSClock()
        overrides = overrides_for_node(list(global_args.parameter_sources) + list(node_args.parameter_sources),
                                       self._fqn)
        for parameter in parameter_overrides or []:
            if not isinstance(parameter, Parameter):
                raise ValueError(f"parameter_overrides must be a list of Parameter; got {parameter!r}")
            overrides[parameter.name] = (parameter.value, "parameter_overrides")
        self._parameters = NodeParameters(overrides, allow_undeclared=allow_undeclared_parameters)
        self._lock = threading.RLock()
        self._publishers: list = []
        self._subscriptions: list = []
        self._timers: list = []
        self._services: list = []
        self._clients: list = []
        self._work: tuple = ()
        self._default_callback_group = MutuallyExclusiveCallbackGroup()
        self._callback_groups = [self._default_callback_group]
        self._executor_ref: weakref.ref[Executor] | None = None
        self._destroyed = False
        self._parameters.declare("use_sim_time", False)
        if automatically_declare_parameters_from_overrides:
            for name, (value, _) in sorted(overrides.items()):
                if not self._parameters.has(name):
                    self._parameters.declare(name, value)
        self._context._track_node(self)
        self._runtime = self._context._runtime()
        self._runtime.add_node(self)
        self._parameter_service = None
        if start_parameter_services:
            self._parameter_service = ParameterService(self)

    # -- identity ------------------------------------------------------------------------------------

    @property
    def context(self):
        return self._context

    @property
    def default_callback_group(self):
        return self._default_callback_group

    @property
    def callback_groups(self):
        return list(self._callback_groups)

    @property
    def publishers(self):
        return iter(list(self._publishers))

    @property
    def subscriptions(self):
        return iter(list(self._subscriptions))

    @property
    def timers(self):
        return iter(list(self._timers))

    @property
    def services(self):
        return iter(list(self._services))

    @property
    def clients(self):
        return iter(list(self._clients))

    def get_name(self) -> str:
        return self._name

    def get_namespace(self) -> str:
        return self._namespace

    def get_fully_qualified_name(self) -> str:
        return self._fqn

    def get_logger(self):
        return self._logger

    def _resolve_node_name(self, name: str) -> str:
        """A node's fully qualified name: ``name`` as is when absolute, else in this node's namespace."""
        if not isinstance(name, str) or not name.strip("/"):
            raise ValueError(f"a node name must be a non-empty string such as '/projector'; got {name!r}")
        return name if name.startswith("/") else fully_qualified_name(self._namespace, name)

    def get_clock(self):
        return self._clock

    def resolve_topic_name(self, topic: str, *, only_expand: bool = False) -> str:
        """Expand ``topic`` (relative, ``~``, absolute) in this node's namespace, then remap it.

        With ``only_expand=True`` the remapping rules are not applied.
        """
        expanded = expand_topic_name(topic, self._name, self._namespace)
        if only_expand:
            return expanded
        return remap_name(self._remap_rules, expanded, self._name, self._namespace,
                          original_node_name=self._original_name)

    def resolve_service_name(self, service: str, *, only_expand: bool = False) -> str:
        expanded = expand_topic_name(service, self._name, self._namespace, is_service=True)
        if only_expand:
            return expanded
        return remap_name(self._remap_rules, expanded, self._name, self._namespace,
                          original_node_name=self._original_name, is_service=True)

    # -- executor link ------------------------------------------------------------------------------

    @property
    def executor(self):
        """The executor this node was added to, or None."""
        return self._executor_ref() if self._executor_ref is not None else None

    @executor.setter
    def executor(self, new_executor) -> None:
        current = self.executor
        if current is new_executor:
            return
        if current is not None:
            current.remove_node(self)
        if new_executor is not None:
            new_executor.add_node(self)

    def _set_executor(self, executor) -> None:
        self._executor_ref = weakref.ref(executor) if executor is not None else None

    def _notify_executor(self) -> None:
        executor = self.executor
        if executor is not None:
            executor._wake.notify()

    # -- entities -------------------------------------------------------------------------------------

    def _check_alive(self) -> None:
        if self._destroyed:
            raise RuntimeError(f"node {self._fqn} was destroyed")
        if not self._context.ok():
            raise NotInitializedException()

    def _changed(self) -> None:
        """Call without holding ``self._lock`` (the runtime's lock is taken after it elsewhere)."""
        with self._lock:
            self._work = tuple(self._timers) + tuple(self._subscriptions) + tuple(self._services)
        self._runtime.mark_dirty(self)
        self._notify_executor()

    def _group(self, callback_group):
        group = callback_group if callback_group is not None else self._default_callback_group
        if group not in self._callback_groups:
            self._callback_groups.append(group)
        return group

    def create_publisher(self, msg_type, topic, qos_profile, *, callback_group=None) -> Publisher:
        """A publisher of ``msg_type`` on ``topic``; ``qos_profile`` is a QoSProfile or an int depth."""
        self._check_alive()
        _check_message_type(msg_type, "create_publisher")
        qos = as_qos_profile(qos_profile)
        publisher = Publisher(self, msg_type, self.resolve_topic_name(topic), qos, self._group(callback_group))
        with self._lock:
            self._publishers.append(publisher)
        self._changed()
        return publisher

    def create_subscription(self, msg_type, topic, callback, qos_profile, *, callback_group=None,
                            raw: bool = False, publishers: KnownPublishers | None = None) -> Subscription:
        """A subscription calling ``callback(msg)`` for each message of ``msg_type`` on ``topic``.

        ``raw=True`` hands the callback the undecoded frames ``[topic, header, *arrays]`` (memoryviews);
        with ``raw=True``, ``msg_type`` may be None to accept any type. ``publishers``: take messages only from
        the publishers this policy accepts (:mod:`dptpu.graph.known_publishers`; its relative node names are
        resolved in this node's namespace); None: from any publisher.
        """
        self._check_alive()
        if not (raw and msg_type is None):
            _check_message_type(msg_type, "create_subscription")
        if not callable(callback):
            raise ValueError(f"subscription callback must be callable; got {callback!r}")
        qos = as_qos_profile(qos_profile)
        if publishers is not None:
            publishers = replace(publishers, nodes=tuple(self._resolve_node_name(name) for name in publishers.nodes))
        subscription = Subscription(self, msg_type, self.resolve_topic_name(topic), callback, qos,
                                    self._group(callback_group), raw=raw, known_publishers=publishers)
        with self._lock:
            self._subscriptions.append(subscription)
        self._changed()
        self._runtime.add_subscription(subscription)
        return subscription

    def create_timer(self, timer_period_sec, callback, callback_group=None, clock=None, autostart=True) -> Timer:
        """A timer calling ``callback()`` every ``timer_period_sec`` seconds (monotonic clock)."""
        self._check_alive()
        timer = Timer(self, callback, timer_period_sec, self._group(callback_group), autostart=autostart)
        with self._lock:
            self._timers.append(timer)
        self._changed()
        return timer

    def create_rate(self, frequency: float, clock=None) -> Rate:
        return Rate(frequency, context=self._context)

    def create_service(self, srv_type, srv_name, callback, *, qos_profile=qos_profile_services_default,
                       callback_group=None) -> Service:
        """A service answering ``callback(request, response) -> response``."""
        self._check_alive()
        _check_service_type(srv_type, "create_service")
        if not callable(callback):
            raise ValueError(f"service callback must be callable; got {callback!r}")
        name = self.resolve_service_name(srv_name)
        with self._lock:
            if any(s.srv_name == name for s in self._services):
                raise ValueError(f"node {self._fqn} already has a service named {name}")
        service = Service(self, srv_type, name, callback, as_qos_profile(qos_profile), self._group(callback_group))
        with self._lock:
            self._services.append(service)
        self._changed()
        self._runtime.add_service(self, service)
        return service

    def create_client(self, srv_type, srv_name, *, qos_profile=qos_profile_services_default,
                      callback_group=None) -> Client:
        """A client of service ``srv_name`` of type ``srv_type``."""
        self._check_alive()
        _check_service_type(srv_type, "create_client")
        client = Client(self, srv_type, self.resolve_service_name(srv_name), as_qos_profile(qos_profile),
                        self._group(callback_group))
        with self._lock:
            self._clients.append(client)
        self._changed()
        self._runtime.add_client(client)
        return client

    def _remove(self, registry: list, entity) -> bool:
        with self._lock:
            if entity not in registry:
                return False
            registry.remove(entity)
            entity._destroyed = True
        self._changed()
        return True

    def destroy_publisher(self, publisher) -> bool:
        if not self._remove(self._publishers, publisher):
            return False
        self._runtime.remove_publisher(publisher)
        return True

    def destroy_subscription(self, subscription) -> bool:
        if not self._remove(self._subscriptions, subscription):
            return False
        self._runtime.remove_subscription(subscription)
        return True

    def destroy_timer(self, timer) -> bool:
        if not self._remove(self._timers, timer):
            return False
        timer.cancel()
        return True

    def destroy_service(self, service) -> bool:
        if not self._remove(self._services, service):
            return False
        self._runtime.remove_service(self, service)
        return True

    def destroy_client(self, client) -> bool:
        if not self._remove(self._clients, client):
            return False
        self._runtime.remove_client(client)
        return True

    def destroy_rate(self, rate) -> bool:
        rate.destroy()
        return True

    def destroy_node(self) -> None:
        """Destroy every entity, withdraw the announcement and leave the executor."""
        if self._destroyed:
            return
        executor = self.executor
        if executor is not None:
            executor.remove_node(self)
        for publisher in list(self._publishers):
            self.destroy_publisher(publisher)
        for subscription in list(self._subscriptions):
            self.destroy_subscription(subscription)
        for timer in list(self._timers):
            self.destroy_timer(timer)
        for service in list(self._services):
            self.destroy_service(service)
        for client in list(self._clients):
            self.destroy_client(client)
        self._destroyed = True
        self._runtime.remove_node(self)
        self._context._untrack_node(self)

    # -- graph queries ------------------------------------------------------------------------------

    def _graph(self):
        return snapshot_from_entries(self._runtime.entries, self._runtime.domain_id)

    def get_node_names(self) -> list[str]:
        return [n.name for n in self._graph().nodes]

    def get_node_names_and_namespaces(self) -> list[tuple[str, str]]:
        return [(n.name, n.namespace) for n in self._graph().nodes]

    def get_fully_qualified_node_names(self) -> list[str]:
        return [n.fully_qualified_name for n in self._graph().nodes]

    def get_topic_names_and_types(self, no_demangle: bool = False) -> list[tuple[str, list[str]]]:
        return [(name, list(t.types)) for name, t in self._graph().topics.items()]

    def get_service_names_and_types(self) -> list[tuple[str, list[str]]]:
        return [(name, list(s.types)) for name, s in self._graph().services.items()]

    def count_publishers(self, topic_name: str) -> int:
        topic = self._graph().topics.get(self.resolve_topic_name(topic_name))
        return topic.publisher_count if topic else 0

    def count_subscribers(self, topic_name: str) -> int:
        topic = self._graph().topics.get(self.resolve_topic_name(topic_name))
        return topic.subscription_count if topic else 0

    def get_publishers_info_by_topic(self, topic_name: str, no_mangle: bool = False) -> list:
        topic = self._graph().topics.get(self.resolve_topic_name(topic_name))
        return list(topic.publishers) if topic else []

    def get_subscriptions_info_by_topic(self, topic_name: str, no_mangle: bool = False) -> list:
        topic = self._graph().topics.get(self.resolve_topic_name(topic_name))
        return list(topic.subscriptions) if topic else []

    # -- parameters (see dptpu.graph.parameters for the rules) -----------------------------------------

    @property
    def allow_undeclared_parameters(self) -> bool:
        return self._parameters._allow_undeclared

    def declare_parameter(self, name, value=None, descriptor=None, ignore_override=False) -> Parameter:
        return self._parameters.declare(name, value, descriptor, ignore_override)

    def declare_parameters(self, namespace, parameters, ignore_override=False) -> list[Parameter]:
        return self._parameters.declare_many(namespace, parameters, ignore_override)

    def undeclare_parameter(self, name) -> None:
        self._parameters.undeclare(name)

    def has_parameter(self, name) -> bool:
        return self._parameters.has(name)

    def get_parameter(self, name) -> Parameter:
        return self._parameters.get(name)

    def get_parameters(self, names) -> list[Parameter]:
        return [self._parameters.get(name) for name in names]

    def get_parameter_or(self, name, alternative_value=None) -> Parameter:
        return self._parameters.get_or(name, alternative_value)

    def get_parameters_by_prefix(self, prefix: str) -> dict[str, Parameter]:
        return self._parameters.by_prefix(prefix)

    def set_parameters(self, parameter_list) -> list:
        return self._parameters.set(parameter_list)

    def set_parameters_atomically(self, parameter_list):
        return self._parameters.set_atomically(parameter_list)

    def describe_parameter(self, name):
        return self._parameters.describe(name)

    def describe_parameters(self, names) -> list:
        return [self._parameters.describe(name) for name in names]

    def get_parameter_types(self, names) -> list:
        types = []
        for name in names:
            try:
                types.append(self._parameters.get_or(name).type_)
            except Exception:  # noqa: BLE001 -- a remote caller's name may be anything: NOT_SET, as rclpy answers
                types.append(Parameter.Type.NOT_SET)
        return types

    def list_parameters(self, prefixes, depth):
        return self._parameters.list(prefixes, depth)

    def add_on_set_parameters_callback(self, callback) -> None:
        self._parameters.add_on_set_parameters_callback(callback)

    def remove_on_set_parameters_callback(self, callback) -> None:
        self._parameters.remove_on_set_parameters_callback(callback)

    def add_post_set_parameters_callback(self, callback) -> None:
        self._parameters.add_post_set_parameters_callback(callback)

    def remove_post_set_parameters_callback(self, callback) -> None:
        self._parameters.remove_post_set_parameters_callback(callback)

    # -- announcement (I/O thread) ------------------------------------------------------------------

    def _announcement(self) -> dict:
        # no lock: called by the I/O thread while holding the runtime's lock (list copies are atomic)
        publishers, subscriptions = list(self._publishers), list(self._subscriptions)
        services, clients = list(self._services), list(self._clients)
        return {"name": self._name, "namespace": self._namespace, "fqn": self._fqn, "gid": self._gid,
                "start_time": self._start_time,
                "publishers": [p._announcement() for p in publishers],
                "subscriptions": [s._announcement() for s in subscriptions],
                "services": [{"name": s.srv_name, "type": s.srv_type.TYPE_NAME} for s in services],
                "clients": [c._announcement() for c in clients]}

    def _stats_signature(self) -> tuple:
        # tuple([...]), not tuple(generator), which fills CPython's tuple free lists (graph/discovery.py)
        return (tuple([(p.published_count, p._subscriber_count) for p in list(self._publishers)])
                + tuple([tuple(s._stats().values()) for s in list(self._subscriptions)]))

    def __repr__(self):
        return f"<Node {self._fqn}>"
