"""Introspection of a running graph: what ``dptpu node|topic|param|service`` compute and print.

One idea per module; the CLI (:mod:`dptpu.cli.introspect_cmd`) is a thin shell over them (arguments, printing,
exit codes):

- :mod:`.graph_view`: the discovery snapshot, hidden nodes filtered, name lookups that raise
  :class:`UnknownNameError`, ``node info`` / ``topic info`` text;
- :mod:`.cli_names`: the names a user gives, made absolute and checked; the message and service classes behind
  them;
- :mod:`.topic_watch`: ``topic echo`` (decoded messages) and ``topic hz`` / ``bw`` (raw frames, a report a
  second) from the CLI's node;
- :mod:`.rate_statistics`: ``topic hz`` (average rate, min/max/std dev of intervals over a window);
- :mod:`.bandwidth_statistics`: ``topic bw`` (bytes/s, message size mean/min/max);
- :mod:`.message_summary`: ``topic echo`` and ``service call`` output, arrays summarized as
  ``{dtype, shape, min, max, mean}``;
- :mod:`.message_from_yaml`: a service request from YAML text;
- :mod:`.parameter_calls`: ``param list/get/set/describe/dump``'s calls to a node's parameter services, each
  bounded in time;
- :mod:`.parameter_text`: ``param get/set/dump`` values and YAML;
- :mod:`.service_call`: ``service call``'s one request;
- :mod:`.cli_node`: the hidden, short-lived node the CLI uses, and the QoS it subscribes with.

User guide: ``docs/introspection.md``.
"""

from .bandwidth_statistics import DEFAULT_BANDWIDTH_WINDOW, BandwidthStatistics, BandwidthWindow, format_bandwidth
from .cli_names import node_name, service_class, service_name, topic_message_class, topic_name
from .cli_node import cli_node, subscription_qos
from .graph_view import (
    UnknownNameError,
    find_node,
    find_service,
    find_topic,
    format_node_info,
    format_topic_info,
    is_hidden_node,
    node_names,
    read_graph,
)
from .message_from_yaml import message_from_data, message_from_yaml
from .message_summary import (
    ArraySummary,
    message_repr,
    message_to_dict,
    message_to_json,
    message_to_yaml,
    summarize_array,
)
from .parameter_calls import (
    PARAMETER_TYPE_NAMES,
    ResponseTimeout,
    describe_parameters,
    format_parameter_description,
    get_parameter,
    parameter_names,
    parameter_types,
    parameter_values,
    serves_parameters,
    set_parameter,
    with_parameter_clients,
)
from .parameter_text import format_parameter_value, parameters_yaml, parse_parameter_value
from .rate_statistics import DEFAULT_RATE_WINDOW, RateStatistics, RateWindow, format_rate
from .service_call import call_service
from .topic_watch import echo_topic, measure_topic

__all__ = [
    "UnknownNameError", "read_graph", "find_node", "find_topic", "find_service", "node_names", "is_hidden_node",
    "format_node_info", "format_topic_info",
    "topic_name", "service_name", "node_name", "topic_message_class", "service_class",
    "echo_topic", "measure_topic",
    "RateWindow", "RateStatistics", "format_rate", "DEFAULT_RATE_WINDOW",
    "BandwidthWindow", "BandwidthStatistics", "format_bandwidth", "DEFAULT_BANDWIDTH_WINDOW",
    "ArraySummary", "summarize_array", "message_to_dict", "message_to_yaml", "message_to_json", "message_repr",
    "message_from_yaml", "message_from_data",
    "PARAMETER_TYPE_NAMES", "ResponseTimeout", "serves_parameters", "with_parameter_clients", "parameter_names",
    "parameter_types", "get_parameter", "set_parameter", "parameter_values", "describe_parameters",
    "format_parameter_description",
    "parse_parameter_value", "format_parameter_value", "parameters_yaml",
    "call_service",
    "cli_node", "subscription_qos",
]
