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
The work is done in :mod:`dptpu.tools.introspection`; this module parses the arguments, prints and picks the
exit code. The user guide is ``docs/introspection.md``.

Each command imports the introspection tools inside its function: ``dptpu`` imports every command module to
build its parser, and the tools bring the runtime (ZeroMQ) with them, which the other commands do not need.
"""
from __future__ import annotations

import sys
import time

#: Default seconds to wait for a named entity to appear in the graph.
DEFAULT_SPIN_TIME_S = 0.5
#: Default seconds to wait for a service (parameter services too) and its response.
DEFAULT_SERVICE_TIMEOUT_S = 5.0


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
    p.add_argument("topic", metavar="TOPIC", help="topic name, e.g. /scanner/points")
    p.add_argument("-v", "--verbose", action="store_true", help="every endpoint, its QoS and its counters")
    _graph_options(p)
    p.set_defaults(func=run_topic_info)
    p = topic.add_parser("type", help="the type of a topic")
    p.add_argument("topic", metavar="TOPIC", help="topic name, e.g. /scanner/points")
    _graph_options(p)
    p.set_defaults(func=run_topic_type)
    p = topic.add_parser("echo", help="print the messages of a topic (arrays summarized)")
    p.add_argument("topic", metavar="TOPIC", help="topic name, e.g. /scanner/points")
    p.add_argument("--once", action="store_true", help="print one message and exit")
    p.add_argument("--count", type=int, default=None, metavar="N", help="exit after N messages")
    p.add_argument("--json", action="store_true", help="one JSON object per line instead of YAML")
    p.add_argument("--qos-depth", type=int, default=10, metavar="N", help="subscription queue depth (default 10)")
    _timeout_option(p, None, "give up after S seconds (exit 1 if no message came; default: wait forever)")
    _graph_options(p)
    p.set_defaults(func=run_topic_echo)
    p = topic.add_parser("hz", help="print the rate of a topic every second")
    p.add_argument("topic", metavar="TOPIC", help="topic name, e.g. /scanner/points")
    p.add_argument("-w", "--window", type=int, default=None, metavar="N",
                   help="messages the statistics use (default 10000)")
    _timeout_option(p, None, "stop after S seconds (default: until Ctrl-C)")
    _graph_options(p)
    p.set_defaults(func=run_topic_hz)
    p = topic.add_parser("bw", help="print the bandwidth of a topic every second")
    p.add_argument("topic", metavar="TOPIC", help="topic name, e.g. /scanner/points")
    p.add_argument("-w", "--window", type=int, default=None, metavar="N",
                   help="messages the statistics use (default 100)")
    _timeout_option(p, None, "stop after S seconds (default: until Ctrl-C)")
    _graph_options(p)
    p.set_defaults(func=run_topic_bw)

    param = _verbs(subparsers, "param", "read and change the parameters of running nodes")
    p = param.add_parser("list", help="parameter names of one node (or of every node)")
    p.add_argument("node", metavar="NODE", nargs="?", default=None,
                   help="fully qualified node name, e.g. /unwrap (default: every node)")
    p.add_argument("--param-type", action="store_true", help="print each parameter's type too")
    _timeout_option(p, DEFAULT_SERVICE_TIMEOUT_S,
                    f"seconds to wait for each node (default {DEFAULT_SERVICE_TIMEOUT_S})")
    _graph_options(p)
    p.set_defaults(func=run_param_list)
    p = param.add_parser("get", help="the value of one parameter")
    p.add_argument("node", metavar="NODE", help="fully qualified node name, e.g. /unwrap")
    p.add_argument("name", metavar="NAME", help="parameter name, e.g. method")
    p.add_argument("--hide-type", action="store_true", help="print only the value")
    _timeout_option(p, DEFAULT_SERVICE_TIMEOUT_S, f"seconds to wait (default {DEFAULT_SERVICE_TIMEOUT_S})")
    _graph_options(p)
    p.set_defaults(func=run_param_get)
    p = param.add_parser("set", help="set one parameter; VALUE is YAML (5 int, 5.0 double, true, [1, 2], text)")
    p.add_argument("node", metavar="NODE", help="fully qualified node name, e.g. /unwrap")
    p.add_argument("name", metavar="NAME", help="parameter name, e.g. method")
    p.add_argument("value", metavar="VALUE", help="new value, typed as YAML reads it (5 is an integer, 5.0 a float)")
    _timeout_option(p, DEFAULT_SERVICE_TIMEOUT_S, f"seconds to wait (default {DEFAULT_SERVICE_TIMEOUT_S})")
    _graph_options(p)
    p.set_defaults(func=run_param_set)
    p = param.add_parser("describe", help="type, description and constraints (read only: fixed at start-up) of "
                                          "parameters")
    p.add_argument("node", metavar="NODE", help="fully qualified node name, e.g. /unwrap")
    p.add_argument("names", metavar="NAME", nargs="+", help="parameter names, e.g. method rig")
    _timeout_option(p, DEFAULT_SERVICE_TIMEOUT_S, f"seconds to wait (default {DEFAULT_SERVICE_TIMEOUT_S})")
    _graph_options(p)
    p.set_defaults(func=run_param_describe)
    p = param.add_parser("dump", help="every parameter of a node as ROS 2 parameter YAML")
    p.add_argument("node", metavar="NODE", help="fully qualified node name, e.g. /unwrap")
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
    p.add_argument("service", metavar="SERVICE", help="service name, e.g. /projector/start_scan")
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
    from dptpu.graph.discovery import resolve_domain_id  # deferred: CLI start-up (see the module docstring)

    return resolve_domain_id(args.domain_id)


def _spin_time(args) -> float:
    _check_seconds(args.spin_time, "--spin-time", allow_none=False)
    return args.spin_time


def _fail(args, message: str) -> int:
    print(f"dptpu {args.command} {args.verb}: {message}", file=sys.stderr, flush=True)
    return 1


# --------------------------------------------------------------------------------------------------
# node
# --------------------------------------------------------------------------------------------------

def run_node_list(args) -> int:
    from dptpu.tools.introspection import node_names, read_graph  # deferred: CLI start-up

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
    from dptpu.tools.introspection import find_node, format_node_info, node_name  # deferred: CLI start-up

    print(format_node_info(find_node(node_name(args.node), _domain(args), wait_s=_spin_time(args))))
    return 0


# --------------------------------------------------------------------------------------------------
# topic
# --------------------------------------------------------------------------------------------------

def run_topic_list(args) -> int:
    from dptpu.tools.introspection import read_graph  # deferred: CLI start-up

    graph = read_graph(_domain(args), include_hidden=args.all)
    if args.count_topics:
        print(len(graph.topics))
        return 0
    for name, info in graph.topics.items():
        types = ", ".join(t for t in info.types if t != "*") or "*"
        print(f"{name} [{types}]" if args.show_types else name)
    return 0


def run_topic_info(args) -> int:
    from dptpu.tools.introspection import find_topic, format_topic_info, topic_name  # deferred: CLI start-up

    info = find_topic(topic_name(args.topic), _domain(args), wait_s=_spin_time(args), need_publisher=False)
    print(format_topic_info(info, verbose=args.verbose))
    return 0


def run_topic_type(args) -> int:
    from dptpu.tools.introspection import find_topic, topic_name  # deferred: CLI start-up

    info = find_topic(topic_name(args.topic), _domain(args), wait_s=_spin_time(args), need_publisher=False)
    for type_name in info.types:
        print(type_name)
    return 0


def run_topic_echo(args) -> int:
    from dptpu.tools.introspection import (  # deferred: CLI start-up
        echo_topic,
        message_to_dict,
        message_to_json,
        message_to_yaml,
        topic_name,
    )

    _check_seconds(args.timeout, "--timeout")
    if args.count is not None and args.count < 1:
        raise ValueError(f"--count must be >= 1; got {args.count}")
    if args.qos_depth < 1:
        raise ValueError(f"--qos-depth must be >= 1; got {args.qos_depth}")
    topic = topic_name(args.topic)

    def on_message(msg) -> None:
        data = message_to_dict(msg)
        if args.json:
            print(message_to_json(data), flush=True)
        else:
            print(message_to_yaml(data) + "\n---", flush=True)

    try:
        printed = echo_topic(topic, _domain(args), on_message, wait_s=_spin_time(args), depth=args.qos_depth,
                             limit=1 if args.once else args.count, timeout_s=args.timeout)
    except KeyboardInterrupt:
        return 0
    if not printed:
        return _fail(args, f"no message on {topic} within {args.timeout:g} s")
    return 0


def _measure(args, on_frames, report) -> int:
    """Subscribe raw to the topic, call ``on_frames(frames)`` per message and ``report()`` every second."""
    from dptpu.tools.introspection import measure_topic, topic_name  # deferred: CLI start-up

    _check_seconds(args.timeout, "--timeout")
    topic = topic_name(args.topic)

    def on_subscribed() -> None:
        if args.verb == "bw":
            print(f"Subscribed to [{topic}]", flush=True)

    try:
        reports = measure_topic(topic, _domain(args), on_frames, report, wait_s=_spin_time(args),
                                timeout_s=args.timeout, on_subscribed=on_subscribed)
    except KeyboardInterrupt:
        return 0
    if not reports:
        return _fail(args, f"fewer than {'2 messages' if args.verb == 'hz' else '1 message'} on {topic} "
                           f"within {args.timeout:g} s")
    return 0


def run_topic_hz(args) -> int:
    from dptpu.tools.introspection import DEFAULT_RATE_WINDOW, RateWindow, format_rate  # deferred: CLI start-up

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
    from dptpu.tools.introspection import (  # deferred: CLI start-up
        DEFAULT_BANDWIDTH_WINDOW,
        BandwidthWindow,
        format_bandwidth,
    )

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

def _with_parameters(args, node_names, work) -> int:
    """Run ``work(client, fqn)`` for each node with a connected parameter client; map failures to exit 1."""
    # deferred: CLI start-up
    from dptpu.graph import ServiceCallError
    from dptpu.tools.introspection import with_parameter_clients

    _check_seconds(args.timeout, "--timeout", allow_none=False)
    try:
        return with_parameter_clients(node_names, _domain(args), work, wait_s=_spin_time(args),
                                      timeout_s=args.timeout)
    except (TimeoutError, ServiceCallError) as exc:
        return _fail(args, str(exc))
    except KeyboardInterrupt:
        return 1


def run_param_list(args) -> int:
    from dptpu.tools.introspection import (  # deferred: CLI start-up
        parameter_names,
        parameter_types,
        read_graph,
        serves_parameters,
    )

    if args.node is None:
        names = [n.fully_qualified_name for n in read_graph(_domain(args)).nodes if serves_parameters(n)]
    else:
        names = [args.node]

    def work(client, fqn: str) -> int:
        parameters = parameter_names(client, fqn, args.timeout)
        if args.node is None:
            print(f"{fqn}:")
        if args.param_type and parameters:
            for name, kind in zip(parameters, parameter_types(client, fqn, parameters, args.timeout)):
                print(f"  {name} (type: {kind})")
        else:
            for name in parameters:
                print(f"  {name}")
        return 0

    return _with_parameters(args, names, work)


def run_param_get(args) -> int:
    from dptpu.tools.introspection import format_parameter_value, get_parameter  # deferred: CLI start-up

    def work(client, fqn: str) -> int:
        type_code, value = get_parameter(client, fqn, args.name, args.timeout)
        print(format_parameter_value(type_code, value, hide_type=args.hide_type))
        return 0

    return _with_parameters(args, [args.node], work)


def run_param_set(args) -> int:
    from dptpu.tools.introspection import parse_parameter_value, set_parameter  # deferred: CLI start-up

    value = parse_parameter_value(args.value)

    def work(client, fqn: str) -> int:
        result = set_parameter(client, fqn, args.name, value, args.timeout)
        if result.successful:
            print("Set parameter successful")
            return 0
        print(f"Setting parameter failed: {result.reason}" if result.reason else "Setting parameter failed")
        return 1

    return _with_parameters(args, [args.node], work)


def run_param_describe(args) -> int:
    from dptpu.tools.introspection import describe_parameters, format_parameter_description  # deferred: start-up

    def work(client, fqn: str) -> int:
        descriptors = describe_parameters(client, fqn, args.names, args.timeout)
        print("\n".join(format_parameter_description(d) for d in descriptors))
        return 0

    return _with_parameters(args, [args.node], work)


def run_param_dump(args) -> int:
    from dptpu.tools.introspection import parameter_values, parameters_yaml  # deferred: CLI start-up

    def work(client, fqn: str) -> int:
        sys.stdout.write(parameters_yaml(fqn, parameter_values(client, fqn, args.timeout)))
        return 0

    return _with_parameters(args, [args.node], work)


# --------------------------------------------------------------------------------------------------
# service
# --------------------------------------------------------------------------------------------------

def run_service_list(args) -> int:
    from dptpu.tools.introspection import read_graph  # deferred: CLI start-up

    graph = read_graph(_domain(args), include_hidden=args.all)
    served = {name: info for name, info in graph.services.items() if info.servers}
    if args.count_services:
        print(len(served))
        return 0
    for name, info in served.items():
        print(f"{name} [{', '.join(info.types)}]" if args.show_types else name)
    return 0


def run_service_type(args) -> int:
    from dptpu.tools.introspection import find_service, service_name  # deferred: CLI start-up

    for type_name in find_service(service_name(args.service), _domain(args), wait_s=_spin_time(args)).types:
        print(type_name)
    return 0


def run_service_call(args) -> int:
    # deferred: CLI start-up
    from dptpu.graph import ServiceCallError
    from dptpu.tools.introspection import (
        call_service,
        message_from_yaml,
        message_repr,
        message_to_dict,
        message_to_json,
        service_class,
        service_name,
    )

    _check_seconds(args.timeout, "--timeout", allow_none=False)
    service = service_name(args.service)
    srv_type = service_class(args.type)
    request = message_from_yaml(srv_type.Request, args.values)

    def before_call() -> None:
        if not args.json:
            print(f"requester: making request: {message_repr(request)}\n", flush=True)

    try:
        response = call_service(service, srv_type, request, _domain(args), wait_s=_spin_time(args),
                                timeout_s=args.timeout, before_call=before_call)
    except (TimeoutError, ServiceCallError) as exc:
        return _fail(args, str(exc))
    except KeyboardInterrupt:
        return 1
    if args.json:
        print(message_to_json(message_to_dict(response)))
    else:
        print(f"response:\n{message_repr(response)}\n")
    return 0
