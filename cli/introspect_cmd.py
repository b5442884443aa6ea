"""``dptpu node|topic|param|service``: look into a running graph, with the ``ros2`` CLI's verbs and output.

Verbs::

    dptpu node list [-a] [-c]                      fully qualified node names, sorted
    dptpu node info NODE                           its subscribers, publishers, service servers and clients
    dptpu topic list [-t] [-c] [-a]                topic names; -t appends " [type]"
    dptpu topic info TOPIC [-v]                    type, publisher/subscription counts (-v: QoS, counters)
    dptpu topic type TOPIC                         its type
    dptpu topic echo TOPIC [--once] [--json]       messages as YAML (or JSON lines), arrays summarized
    dptpu topic hz TOPIC [--window N]              rate: average, min/max/std dev of the intervals
    dptpu topic bw TOPIC [--window N]              bandwidth: bytes/s and message size mean/min/max
    dptpu param list [NODE] [--param-type]         parameter names
    dptpu param get NODE NAME                      "Integer value is: 5"
    dptpu param set NODE NAME VALUE                VALUE is YAML: 5 int, 5.0 double, true, [1, 2], text
    dptpu param dump NODE                          ROS 2 parameter YAML (/node: ros__parameters: ...)
    dptpu service list [-t] [-c]                   served services
    dptpu service type SERVICE                     its type
    dptpu service call SERVICE TYPE [YAML]         one request, e.g. '{data: true}'; prints the response

Every command takes ``--domain-id`` (default ``$DPTPU_DOMAIN_ID``, ``$ROS_DOMAIN_ID``, 0) and
``--spin-time S`` (how long to wait for a named node/topic/service to appear; default 0.5 s).
Exit codes: 0 done; 1 a runtime failure (no message or response within ``--timeout``, a parameter
refused, a service error); 2 bad input or an unknown node, topic or service (one line on stderr).
The work is done in :mod:`dptpu.tools.introspection`; the user guide is ``docs/introspection.md``.
"""
from __future__ import annotations

import re
import sys
import time

#: Default seconds to wait for a named entity to appear in the graph.
DEFAULT_SPIN_TIME_S = 0.5
#: Default seconds to wait for a service (parameter services too) and its response.
DEFAULT_SERVICE_TIMEOUT_S = 5.0
#: Seconds between two ``hz`` / ``bw`` reports (as ros2).
REPORT_PERIOD_S = 1.0

_PARAMETER_TYPE_NAMES = ("not set", "boolean", "integer", "double", "string", "byte array", "boolean array",
                         "integer array", "double array", "string array")


# --------------------------------------------------------------------------------------------------
# Parsers
# --------------------------------------------------------------------------------------------------

def _graph_options(parser, *, spin_time: bool = True) -> None:
    parser.add_argument("--domain-id", type=int, default=None, metavar="ID",
                        help="graph domain (default: $DPTPU_DOMAIN_ID, $ROS_DOMAIN_ID, 0)")
    if spin_time:
        parser.add_argument("--spin-time", type=float, default=DEFAULT_SPIN_TIME_S, metavar="S",
                            help=f"seconds to wait for the name to appear in the graph (default {DEFAULT_SPIN_TIME_S})")


def _timeout_option(parser, default, what: str) -> None:
    parser.add_argument("--timeout", type=float, default=default, metavar="S", help=what)


def _verbs(subparsers, name: str, help_text: str):
    parser = subparsers.add_parser(name, help=help_text, description=help_text + " (see docs/introspection.md)")
    return parser.add_subparsers(dest="verb", metavar="VERB", required=True)


def register(subparsers) -> None:
    node = _verbs(subparsers, "node", "list and inspect the nodes of a running graph")
    p = node.add_parser("list", help="fully qualified node names, sorted")
    p.add_argument("-a", "--all", action="store_true", help="include hidden nodes (names starting with '_')")
    p.add_argument("-c", "--count-nodes", action="store_true", help="print only the number of nodes")
    _graph_options(p, spin_time=False)
    p.set_defaults(func=run_node_list)
    p = node.add_parser("info", help="a node's subscribers, publishers, service servers and clients")
    p.add_argument("node", metavar="NODE", help="fully qualified node name, e.g. /talker")
    _graph_options(p)
    p.set_defaults(func=run_node_info)

    topic = _verbs(subparsers, "topic", "list, inspect, echo and measure the topics of a running graph")
    p = topic.add_parser("list", help="topic names, sorted")
    p.add_argument("-t", "--show-types", action="store_true", help="append the type: /topic [type]")
    p.add_argument("-c", "--count-topics", action="store_true", help="print only the number of topics")
    p.add_argument("-a", "--all", action="store_true", help="include the topics of hidden nodes")
    _graph_options(p, spin_time=False)
    p.set_defaults(func=run_topic_list)
    p = topic.add_parser("info", help="type and publisher/subscription counts of a topic")
    p.add_argument("topic", metavar="TOPIC")
    p.add_argument("-v", "--verbose", action="store_true", help="every endpoint, its QoS and its counters")
    _graph_options(p)
    p.set_defaults(func=run_topic_info)
    p = topic.add_parser("type", help="the type of a topic")
    p.add_argument("topic", metavar="TOPIC")
    _graph_options(p)
    p.set_defaults(func=run_topic_type)
    p = topic.add_parser("echo", help="print the messages of a topic (arrays summarized)")
    p.add_argument("topic", metavar="TOPIC")
    p.add_argument("--once", action="store_true", help="print one message and exit")
    p.add_argument("--count", type=int, default=None, metavar="N", help="exit after N messages")
    p.add_argument("--json", action="store_true", help="one JSON object per line instead of YAML")
    p.add_argument("--qos-depth", type=int, default=10, metavar="N", help="subscription queue depth (default 10)")
    _timeout_option(p, None, "give up after S seconds (exit 1 if no message came; default: wait forever)")
    _graph_options(p)
    p.set_defaults(func=run_topic_echo)
    p = topic.add_parser("hz", help="print the rate of a topic every second")
    p.add_argument("topic", metavar="TOPIC")
    p.add_argument("-w", "--window", type=int, default=None, metavar="N",
                   help="messages the statistics use (default 10000)")
    _timeout_option(p, None, "stop after S seconds (default: until Ctrl-C)")
    _graph_options(p)
    p.set_defaults(func=run_topic_hz)
    p = topic.add_parser("bw", help="print the bandwidth of a topic every second")
    p.add_argument("topic", metavar="TOPIC")
    p.add_argument("-w", "--window", type=int, default=None, metavar="N",
                   help="messages the statistics use (default 100)")
    _timeout_option(p, None, "stop after S seconds (default: until Ctrl-C)")
    _graph_options(p)
    p.set_defaults(func=run_topic_bw)

    param = _verbs(subparsers, "param", "read and change the parameters of running nodes")
    p = param.add_parser("list", help="parameter names of one node (or of every node)")
    p.add_argument("node", metavar="NODE", nargs="?", default=None)
    p.add_argument("--param-type", action="store_true", help="print each parameter's type too")
    _timeout_option(p, DEFAULT_SERVICE_TIMEOUT_S,
                    f"seconds to wait for each node (default {DEFAULT_SERVICE_TIMEOUT_S})")
    _graph_options(p)
    p.set_defaults(func=run_param_list)
    p = param.add_parser("get", help="the value of one parameter")
    p.add_argument("node", metavar="NODE")
    p.add_argument("name", metavar="NAME")
    p.add_argument("--hide-type", action="store_true", help="print only the value")
    _timeout_option(p, DEFAULT_SERVICE_TIMEOUT_S, f"seconds to wait (default {DEFAULT_SERVICE_TIMEOUT_S})")
    _graph_options(p)
    p.set_defaults(func=run_param_get)
    p = param.add_parser("set", help="set one parameter; VALUE is YAML (5 int, 5.0 double, true, [1, 2], text)")
    p.add_argument("node", metavar="NODE")
    p.add_argument("name", metavar="NAME")
    p.add_argument("value", metavar="VALUE")
    _timeout_option(p, DEFAULT_SERVICE_TIMEOUT_S, f"seconds to wait (default {DEFAULT_SERVICE_TIMEOUT_S})")
    _graph_options(p)
    p.set_defaults(func=run_param_set)
    p = param.add_parser("dump", help="every parameter of a node as ROS 2 parameter YAML")
    p.add_argument("node", metavar="NODE")
    _timeout_option(p, DEFAULT_SERVICE_TIMEOUT_S, f"seconds to wait (default {DEFAULT_SERVICE_TIMEOUT_S})")
    _graph_options(p)
    p.set_defaults(func=run_param_dump)

    service = _verbs(subparsers, "service", "list and call the services of a running graph")
    p = service.add_parser("list", help="served service names, sorted")
    p.add_argument("-t", "--show-types", action="store_true", help="append the type: /service [type]")
    p.add_argument("-c", "--count-services", action="store_true", help="print only the number of services")
    p.add_argument("-a", "--all", action="store_true", help="include the services of hidden nodes")
    _graph_options(p, spin_time=False)
    p.set_defaults(func=run_service_list)
    p = service.add_parser("type", help="the type of a service")
    p.add_argument("service", metavar="SERVICE")
    _graph_options(p)
    p.set_defaults(func=run_service_type)
    p = service.add_parser("call", help="call a service once and print the response")
    p.add_argument("service", metavar="SERVICE", help="e.g. /talker/reset")
    p.add_argument("type", metavar="TYPE", help="e.g. std_srvs/srv/Trigger (or std_srvs/Trigger)")
    p.add_argument("values", metavar="VALUES", nargs="?", default="{}",
                   help="the request as YAML, e.g. '{data: true}' (default: '{}')")
    p.add_argument("--json", action="store_true", help="print only the response, as one JSON object")
    _timeout_option(p, DEFAULT_SERVICE_TIMEOUT_S,
                    f"seconds to wait for the server and its response (default {DEFAULT_SERVICE_TIMEOUT_S})")
    _graph_options(p)
    p.set_defaults(func=run_service_call)


# --------------------------------------------------------------------------------------------------
# Helpers
# --------------------------------------------------------------------------------------------------

def _check_seconds(value, option: str, *, allow_none: bool = True) -> None:
    if value is None and allow_none:
        return
    if value is None or not value >= 0:
        raise ValueError(f"{option} must be a number of seconds >= 0; got {value}")


def _domain(args) -> int:
    from dptpu.graph.discovery import resolve_domain_id

    return resolve_domain_id(args.domain_id)


def _spin_time(args) -> float:
    _check_seconds(args.spin_time, "--spin-time", allow_none=False)
    return args.spin_time


def _topic_name(name: str) -> str:
    from dptpu.graph.names import expand_topic_name

    return expand_topic_name(name, "_dptpu_cli", "/")


def _service_name(name: str) -> str:
    from dptpu.graph.names import expand_topic_name

    return expand_topic_name(name, "_dptpu_cli", "/", is_service=True)


def _node_name(name: str) -> str:
    if not isinstance(name, str) or not re.match(r"^/?[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*$", name):
        raise ValueError(f"node name must look like /name or /namespace/name; got {name!r}")
    return name if name.startswith("/") else "/" + name


def _fail(args, message: str) -> int:
    print(f"dptpu {args.command} {args.verb}: {message}", file=sys.stderr, flush=True)
    return 1


def _message_class(info, *, required: bool):
    """The registered class of a topic's single type; None (raw) when unknown and not ``required``."""
    from dptpu.messages.registry import is_registered, lookup

    types = [t for t in info.types if t != "*"]
    if len(types) != 1:
        raise ValueError(f"topic {info.name} has {len(types)} types ({', '.join(types) or 'none'}); "
                         "expected exactly one")
    if is_registered(types[0]):
        return lookup(types[0])
    if required:
        raise ValueError(f"topic {info.name} has type {types[0]}, which this dptpu does not know; "
                         "`dptpu topic hz` and `bw` still work on it")
    return None


class _Timeout(Exception):
    pass


def _result(future, timeout_s: float, what: str):
    if not future.wait(timeout_s):
        raise _Timeout(f"no response to {what} within {timeout_s:g} s")
    return future.result()


# --------------------------------------------------------------------------------------------------
# node
# --------------------------------------------------------------------------------------------------

def run_node_list(args) -> int:
    from dptpu.tools.introspection import node_names, read_graph

    names = node_names(read_graph(_domain(args), include_hidden=args.all))
    if args.count_nodes:
        print(len(names))
        return 0
    duplicates = sorted({name for name in names if names.count(name) > 1})
    if duplicates:
        print(f"WARNING: Be aware that there are nodes in the graph that share an exact name, which can have "
              f"unintended side effects: {', '.join(duplicates)}", file=sys.stderr)
    for name in names:
        print(name)
    return 0


def run_node_info(args) -> int:
    from dptpu.tools.introspection import find_node, format_node_info

    print(format_node_info(find_node(_node_name(args.node), _domain(args), wait_s=_spin_time(args))))
    return 0


# --------------------------------------------------------------------------------------------------
# topic
# --------------------------------------------------------------------------------------------------

def run_topic_list(args) -> int:
    from dptpu.tools.introspection import read_graph

    graph = read_graph(_domain(args), include_hidden=args.all)
    if args.count_topics:
        print(len(graph.topics))
        return 0
    for name, info in graph.topics.items():
        types = ", ".join(t for t in info.types if t != "*") or "*"
        print(f"{name} [{types}]" if args.show_types else name)
    return 0


def run_topic_info(args) -> int:
    from dptpu.tools.introspection import find_topic, format_topic_info

    info = find_topic(_topic_name(args.topic), _domain(args), wait_s=_spin_time(args), need_publisher=False)
    print(format_topic_info(info, verbose=args.verbose))
    return 0


def run_topic_type(args) -> int:
    from dptpu.tools.introspection import find_topic

    info = find_topic(_topic_name(args.topic), _domain(args), wait_s=_spin_time(args), need_publisher=False)
    for type_name in info.types:
        print(type_name)
    return 0


def _spin_until(executor, done, deadline) -> bool:
    """Spin until ``done()``; False when ``deadline`` (monotonic s, or None) passed first."""
    while not done():
        if deadline is None:
            executor.spin_once(timeout_sec=0.5)
            continue
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            return False
        executor.spin_once(timeout_sec=remaining)
    return True


def run_topic_echo(args) -> int:
    from dptpu.tools.introspection import (cli_node, find_topic, message_to_dict, message_to_json, message_to_yaml,
                                           subscription_qos)

    _check_seconds(args.timeout, "--timeout")
    if args.count is not None and args.count < 1:
        raise ValueError(f"--count must be >= 1; got {args.count}")
    if args.qos_depth < 1:
        raise ValueError(f"--qos-depth must be >= 1; got {args.qos_depth}")
    limit = 1 if args.once else args.count
    topic = _topic_name(args.topic)
    domain = _domain(args)
    info = find_topic(topic, domain, wait_s=_spin_time(args))
    msg_type = _message_class(info, required=True)
    qos = subscription_qos([p.qos for p in info.publishers], depth=args.qos_depth)
    printed = [0]

    def on_message(msg) -> None:
        if limit is not None and printed[0] >= limit:
            return
        data = message_to_dict(msg)
        if args.json:
            print(message_to_json(data), flush=True)
        else:
            print(message_to_yaml(data) + "\n---", flush=True)
        printed[0] += 1

    deadline = None if args.timeout is None else time.monotonic() + args.timeout
    try:
        with cli_node(domain) as (node, executor):
            node.create_subscription(msg_type, topic, on_message, qos)
            finished = _spin_until(executor, lambda: limit is not None and printed[0] >= limit, deadline)
    except KeyboardInterrupt:
        return 0
    if not finished and not printed[0]:
        return _fail(args, f"no message on {topic} within {args.timeout:g} s")
    return 0


def _measure(args, on_frames, report) -> int:
    """Subscribe raw to the topic, call ``on_frames(views)`` per message and ``report()`` every second."""
    from dptpu.tools.introspection import cli_node, find_topic, subscription_qos

    _check_seconds(args.timeout, "--timeout")
    topic = _topic_name(args.topic)
    domain = _domain(args)
    info = find_topic(topic, domain, wait_s=_spin_time(args))
    msg_type = _message_class(info, required=False)
    qos = subscription_qos([p.qos for p in info.publishers], depth=100)
    deadline = None if args.timeout is None else time.monotonic() + args.timeout
    reports = 0
    try:
        with cli_node(domain) as (node, executor):
            node.create_subscription(msg_type, topic, on_frames, qos, raw=True)
            if args.verb == "bw":
                print(f"Subscribed to [{topic}]", flush=True)
            next_report = time.monotonic() + REPORT_PERIOD_S
            while True:
                now = time.monotonic()
                if deadline is not None and now >= deadline:
                    break
                until = next_report if deadline is None else min(next_report, deadline)
                executor.spin_once(timeout_sec=max(0.0, until - now))
                if time.monotonic() >= next_report:
                    next_report += REPORT_PERIOD_S
                    reports += bool(report())
    except KeyboardInterrupt:
        return 0
    if not reports:
        return _fail(args, f"fewer than {'2 messages' if args.verb == 'hz' else '1 message'} on {topic} "
                           f"within {args.timeout:g} s")
    return 0


def run_topic_hz(args) -> int:
    from dptpu.tools.introspection import RateWindow, format_rate
    from dptpu.tools.introspection.rate_statistics import DEFAULT_RATE_WINDOW

    window = RateWindow(DEFAULT_RATE_WINDOW if args.window is None else args.window)
    seen = [0]

    def report() -> bool:
        stats = window.statistics()
        if stats is None:
            return False
        if window.total_count == seen[0]:
            print("no new messages", flush=True)
            return True
        seen[0] = window.total_count
        print(format_rate(stats), flush=True)
        return True

    return _measure(args, lambda frames: window.add(time.monotonic()), report)


def run_topic_bw(args) -> int:
    from dptpu.tools.introspection import BandwidthWindow, format_bandwidth
    from dptpu.tools.introspection.bandwidth_statistics import DEFAULT_BANDWIDTH_WINDOW

    window = BandwidthWindow(DEFAULT_BANDWIDTH_WINDOW if args.window is None else args.window)

    def on_frames(frames) -> None:
        window.add(time.monotonic(), sum(memoryview(frame).nbytes for frame in frames))

    def report() -> bool:
        stats = window.statistics(time.monotonic())
        if stats is None:
            return False
        print(format_bandwidth(stats), flush=True)
        return True

    return _measure(args, on_frames, report)


# --------------------------------------------------------------------------------------------------
# param
# --------------------------------------------------------------------------------------------------

def _parameter_node(args, name: str, domain: int):
    """The NodeInfo of ``name``, which must serve the parameter services."""
    from dptpu.tools.introspection import find_node

    info = find_node(_node_name(name), domain, wait_s=_spin_time(args))
    if f"{info.fully_qualified_name}/get_parameters" not in {service for service, _ in info.services}:
        raise ValueError(f"node {info.fully_qualified_name} serves no parameter services (it was created with "
                         "start_parameter_services=False)")
    return info


def _parameter_client(node, fqn: str, timeout_s: float):
    from dptpu.graph.parameter_client import AsyncParameterClient

    client = AsyncParameterClient(node, fqn)
    if not client.wait_for_services(timeout_sec=timeout_s):
        raise _Timeout(f"the parameter services of {fqn} did not become available within {timeout_s:g} s")
    return client


def _with_parameters(args, node_names, work) -> int:
    """Run ``work(client, fqn)`` for each node with a connected parameter client; map failures to exit 1."""
    from dptpu.graph import ServiceCallError
    from dptpu.tools.introspection import cli_node

    _check_seconds(args.timeout, "--timeout", allow_none=False)
    domain = _domain(args)
    infos = [_parameter_node(args, name, domain) for name in node_names]
    try:
        with cli_node(domain) as (node, _executor):
            code = 0
            for info in infos:
                client = _parameter_client(node, info.fully_qualified_name, args.timeout)
                code = max(code, work(client, info.fully_qualified_name) or 0)
            return code
    except (_Timeout, ServiceCallError) as exc:
        return _fail(args, str(exc))
    except KeyboardInterrupt:
        return 1


def _parameter_names(client, fqn: str, timeout_s: float) -> list[str]:
    return client.names_of(_result(client.list_parameters(), timeout_s, f"list_parameters of {fqn}"))


def run_param_list(args) -> int:
    from dptpu.tools.introspection import read_graph

    if args.node is None:
        graph = read_graph(_domain(args))
        names = [n.fully_qualified_name for n in graph.nodes
                 if f"{n.fully_qualified_name}/get_parameters" in {s for s, _ in n.services}]
    else:
        names = [args.node]

    def work(client, fqn: str) -> int:
        parameters = _parameter_names(client, fqn, args.timeout)
        if args.node is None:
            print(f"{fqn}:")
        if args.param_type and parameters:
            response = _result(client.get_parameter_types(parameters), args.timeout, f"get_parameter_types of {fqn}")
            for name, code in zip(parameters, [int(c) for c in response.types]):
                kind = _PARAMETER_TYPE_NAMES[code] if 0 <= code < len(_PARAMETER_TYPE_NAMES) else str(code)
                print(f"  {name} (type: {kind})")
        else:
            for name in parameters:
                print(f"  {name}")
        return 0

    return _with_parameters(args, names, work)


def run_param_get(args) -> int:
    from dptpu.graph import Parameter
    from dptpu.tools.introspection import UnknownNameError, format_parameter_value
    from dptpu.graph.parameters import parameter_value_to_python

    def work(client, fqn: str) -> int:
        response = _result(client.get_parameters([args.name]), args.timeout, f"get_parameters of {fqn}")
        value = response.values[0]
        if value.type == Parameter.Type.NOT_SET:
            names = _parameter_names(client, fqn, args.timeout)
            if args.name not in names:
                raise UnknownNameError(f"node {fqn} has no parameter {args.name!r}; its parameters: "
                                       f"{', '.join(names) or '(none)'}")
        print(format_parameter_value(value.type, parameter_value_to_python(value), hide_type=args.hide_type))
        return 0

    return _with_parameters(args, [args.node], work)


def run_param_set(args) -> int:
    from dptpu.graph import Parameter
    from dptpu.tools.introspection import parse_parameter_value

    value = parse_parameter_value(args.value)

    def work(client, fqn: str) -> int:
        response = _result(client.set_parameters([Parameter(args.name, value=value)]), args.timeout,
                           f"set_parameters of {fqn}")
        result = response.results[0]
        if result.successful:
            print("Set parameter successful")
            return 0
        print(f"Setting parameter failed: {result.reason}" if result.reason else "Setting parameter failed")
        return 1

    return _with_parameters(args, [args.node], work)


def run_param_dump(args) -> int:
    from dptpu.tools.introspection import parameters_yaml

    def work(client, fqn: str) -> int:
        names = _parameter_names(client, fqn, args.timeout)
        response = _result(client.get_parameters(names), args.timeout, f"get_parameters of {fqn}")
        sys.stdout.write(parameters_yaml(fqn, dict(zip(names, client.values_of(response)))))
        return 0

    return _with_parameters(args, [args.node], work)


# --------------------------------------------------------------------------------------------------
# service
# --------------------------------------------------------------------------------------------------

def run_service_list(args) -> int:
    from dptpu.tools.introspection import read_graph

    graph = read_graph(_domain(args), include_hidden=args.all)
    served = {name: info for name, info in graph.services.items() if info.servers}
    if args.count_services:
        print(len(served))
        return 0
    for name, info in served.items():
        print(f"{name} [{', '.join(info.types)}]" if args.show_types else name)
    return 0


def run_service_type(args) -> int:
    from dptpu.tools.introspection import find_service

    for type_name in find_service(_service_name(args.service), _domain(args), wait_s=_spin_time(args)).types:
        print(type_name)
    return 0


def _service_class(type_name: str):
    from dptpu.graph.interfaces import lookup_service

    match = re.match(r"^([a-z][a-z0-9_]*)/(?:srv/)?([A-Z][A-Za-z0-9]*)$", type_name or "")
    if match is None:
        raise ValueError(f"service type must look like package/srv/Name (e.g. std_srvs/srv/Trigger); "
                         f"got {type_name!r}")
    full = f"{match.group(1)}/srv/{match.group(2)}"
    try:
        return lookup_service(full)
    except KeyError as exc:
        raise ValueError(exc.args[0]) from None


def run_service_call(args) -> int:
    from dptpu.graph import ServiceCallError
    from dptpu.tools.introspection import (cli_node, find_service, message_from_yaml, message_repr, message_to_dict,
                                           message_to_json)

    _check_seconds(args.timeout, "--timeout", allow_none=False)
    service = _service_name(args.service)
    srv_type = _service_class(args.type)
    request = message_from_yaml(srv_type.Request, args.values)
    domain = _domain(args)
    info = find_service(service, domain, wait_s=_spin_time(args))
    if srv_type.TYPE_NAME not in info.types:
        raise ValueError(f"service {service} has type {', '.join(info.types)}; got {srv_type.TYPE_NAME}")
    try:
        with cli_node(domain) as (node, _executor):
            client = node.create_client(srv_type, service)
            if not client.wait_for_service(timeout_sec=args.timeout):
                return _fail(args, f"service {service} did not become available within {args.timeout:g} s")
            if not args.json:
                print(f"requester: making request: {message_repr(request)}\n", flush=True)
            response = client.call(request, timeout_sec=args.timeout)
    except TimeoutError as exc:
        return _fail(args, str(exc))
    except ServiceCallError as exc:
        return _fail(args, str(exc))
    except KeyboardInterrupt:
        return 1
    if args.json:
        print(message_to_json(message_to_dict(response)))
    else:
        print(f"response:\n{message_repr(response)}\n")
    return 0

