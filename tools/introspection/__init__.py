"""Introspection of a running graph: what ``dptpu node|topic|param|service`` compute and print.

One idea per module; the CLI (:mod:`dptpu.cli.introspect_cmd`) is a thin shell over them:

- :mod:`.graph_view`: the discovery snapshot, hidden nodes filtered, name lookups that raise
  :class:`UnknownNameError`, ``node info`` / ``topic info`` text;
- :mod:`.rate_statistics`: ``topic hz`` (average rate, min/max/std dev of intervals over a window);
- :mod:`.bandwidth_statistics`: ``topic bw`` (bytes/s, message size mean/min/max);
- :mod:`.message_summary`: ``topic echo`` and ``service call`` output, arrays summarized as
  ``{dtype, shape, min, max, mean}``;
- :mod:`.message_from_yaml`: a service request from YAML text;
- :mod:`.parameter_text`: ``param get/set/dump`` values and YAML;
- :mod:`.cli_node`: the hidden, short-lived node the CLI uses, and the QoS it subscribes with.

User guide: ``docs/introspection.md``.
"""

from .bandwidth_statistics import BandwidthStatistics, BandwidthWindow, format_bandwidth
from .cli_node import cli_node, subscription_qos
from .graph_view import (UnknownNameError, find_node, find_service, find_topic, format_node_info, format_topic_info,
                         is_hidden_node, node_names, read_graph)
from .message_from_yaml import message_from_data, message_from_yaml
from .message_summary import (ArraySummary, message_repr, message_to_dict, message_to_json, message_to_yaml,
                              summarize_array)
from .parameter_text import format_parameter_value, parameters_yaml, parse_parameter_value
from .rate_statistics import RateStatistics, RateWindow, format_rate

__all__ = [
    "UnknownNameError", "read_graph", "find_node", "find_topic", "find_service", "node_names", "is_hidden_node",
    "format_node_info", "format_topic_info",
    "RateWindow", "RateStatistics", "format_rate",
    "BandwidthWindow", "BandwidthStatistics", "format_bandwidth",
    "ArraySummary", "summarize_array", "message_to_dict", "message_to_yaml", "message_to_json", "message_repr",
    "message_from_yaml", "message_from_data",
    "parse_parameter_value", "format_parameter_value", "parameters_yaml",
    "cli_node", "subscription_qos",
]
