"""``dptpu param``'s calls: a node's parameter services found and reached, and each request waited for.

Every wait is bounded: a service that does not appear, or a response that does not come, within ``timeout_s``
raises :class:`ResponseTimeout` (a ``TimeoutError``: the CLI's exit code 1); a node that serves no parameter
services, or has no such parameter, is a ``ValueError`` (exit code 2).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from dptpu.graph import Parameter
from dptpu.graph.parameter_client import AsyncParameterClient
from dptpu.graph.parameters import parameter_value_to_python

from .cli_names import node_name
from .cli_node import cli_node
from .graph_view import UnknownNameError, find_node

__all__ = ["PARAMETER_TYPE_NAMES", "ResponseTimeout", "wait_result", "parameter_node", "serves_parameters",
           "with_parameter_clients", "parameter_names", "parameter_types", "get_parameter", "set_parameter",
           "parameter_values", "describe_parameters", "format_parameter_description"]

#: ``rcl_interfaces/msg/ParameterType`` codes as ``ros2 param list --param-type`` names them.
PARAMETER_TYPE_NAMES = ("not set", "boolean", "integer", "double", "string", "byte array", "boolean array",
                        "integer array", "double array", "string array")


class ResponseTimeout(TimeoutError):
    """A parameter service did not appear, or did not answer, in time."""


def wait_result(future, timeout_s: float, what: str):
    """The result of ``future``; :class:`ResponseTimeout` naming ``what`` when it does not come in time."""
    if not future.wait(timeout_s):
        raise ResponseTimeout(f"no response to {what} within {timeout_s:g} s")
    return future.result()


def serves_parameters(info) -> bool:
    """Whether the node of ``info`` (a NodeInfo) serves the parameter services."""
    return f"{info.fully_qualified_name}/get_parameters" in {service for service, _ in info.services}


def parameter_node(name: str, domain_id: int, *, wait_s: float):
    """The NodeInfo of ``name``, which must serve the parameter services."""
    info = find_node(node_name(name), domain_id, wait_s=wait_s)
    if not serves_parameters(info):
        raise ValueError(f"node {info.fully_qualified_name} serves no parameter services (it was created with "
                         "start_parameter_services=False)")
    return info


def _parameter_client(node, fqn: str, timeout_s: float) -> AsyncParameterClient:
    client = AsyncParameterClient(node, fqn)
    if not client.wait_for_services(timeout_sec=timeout_s):
        raise ResponseTimeout(f"the parameter services of {fqn} did not become available within {timeout_s:g} s")
    return client


def with_parameter_clients(node_names: Sequence[str], domain_id: int, work: Callable, *, wait_s: float,
                           timeout_s: float) -> int:
    """Run ``work(client, fqn)`` for each node with a connected parameter client; the largest code it returns.

    Every node is looked up first (a missing one raises before any call); one hidden CLI node makes the calls.
    """
    infos = [parameter_node(name, domain_id, wait_s=wait_s) for name in node_names]
    with cli_node(domain_id) as (node, _executor):
        code = 0
        for info in infos:
            client = _parameter_client(node, info.fully_qualified_name, timeout_s)
            code = max(code, work(client, info.fully_qualified_name) or 0)
        return code


def parameter_names(client, fqn: str, timeout_s: float) -> list[str]:
    """The names of every parameter of ``fqn``."""
    return client.names_of(wait_result(client.list_parameters(), timeout_s, f"list_parameters of {fqn}"))


def parameter_types(client, fqn: str, names: Sequence[str], timeout_s: float) -> list[str]:
    """The type of each of ``names``, as :data:`PARAMETER_TYPE_NAMES` words (an unknown code as its number)."""
    response = wait_result(client.get_parameter_types(list(names)), timeout_s, f"get_parameter_types of {fqn}")
    codes = [int(code) for code in response.types]
    return [PARAMETER_TYPE_NAMES[code] if 0 <= code < len(PARAMETER_TYPE_NAMES) else str(code) for code in codes]


def get_parameter(client, fqn: str, name: str, timeout_s: float):
    """``(type code, Python value)`` of parameter ``name``; :class:`UnknownNameError` when ``fqn`` has none."""
    response = wait_result(client.get_parameters([name]), timeout_s, f"get_parameters of {fqn}")
    value = response.values[0]
    if value.type == Parameter.Type.NOT_SET:
        names = parameter_names(client, fqn, timeout_s)
        if name not in names:
            raise UnknownNameError(f"node {fqn} has no parameter {name!r}; its parameters: "
                                   f"{', '.join(names) or '(none)'}")
    return value.type, parameter_value_to_python(value)


def describe_parameters(client, fqn: str, names: Sequence[str], timeout_s: float) -> list:
    """The ``ParameterDescriptor`` of each of ``names``; :class:`UnknownNameError` naming those ``fqn`` lacks."""
    known = parameter_names(client, fqn, timeout_s)
    missing = [name for name in names if name not in known]
    if missing:
        raise UnknownNameError(f"node {fqn} has no parameter {', '.join(repr(n) for n in missing)}; its parameters: "
                               f"{', '.join(known) or '(none)'}")
    response = wait_result(client.describe_parameters(list(names)), timeout_s, f"describe_parameters of {fqn}")
    return list(response.descriptors)


def format_parameter_description(descriptor) -> str:
    """``ros2 param describe``'s text of one descriptor: name, type, description and constraints (read-only: what
    only a restart changes)."""
    code = int(descriptor.type)
    lines = [f"Parameter name: {descriptor.name}",
             f"  Type: {PARAMETER_TYPE_NAMES[code] if 0 <= code < len(PARAMETER_TYPE_NAMES) else code}"]
    if descriptor.description:
        lines.append(f"  Description: {descriptor.description}")
    constraints = []
    if descriptor.read_only:
        constraints.append("    Read only: true")
    if descriptor.dynamic_typing:
        constraints.append("    Dynamic typing: true")
    for bounds in (*descriptor.floating_point_range, *descriptor.integer_range):
        constraints.append(f"    Min value: {bounds.from_value}")
        constraints.append(f"    Max value: {bounds.to_value}")
        if bounds.step:
            constraints.append(f"    Step: {bounds.step}")
    if descriptor.additional_constraints:
        constraints.append(f"    Additional constraints: {descriptor.additional_constraints}")
    if constraints:
        lines += ["  Constraints:", *constraints]
    return "\n".join(lines)


def set_parameter(client, fqn: str, name: str, value, timeout_s: float):
    """Set one parameter; the ``SetParametersResult`` (``successful``, ``reason``)."""
    response = wait_result(client.set_parameters([Parameter(name, value=value)]), timeout_s,
                           f"set_parameters of {fqn}")
    return response.results[0]


def parameter_values(client, fqn: str, timeout_s: float) -> dict:
    """Every parameter of ``fqn``: ``{name: Python value}``."""
    names = parameter_names(client, fqn, timeout_s)
    response = wait_result(client.get_parameters(names), timeout_s, f"get_parameters of {fqn}")
    return dict(zip(names, client.values_of(response)))
