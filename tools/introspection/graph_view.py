"""What ``dptpu node|topic|service list/info`` show: the discovery snapshot, filtered and formatted.

The graph is read straight from the domain's announcement folder (:mod:`dptpu.graph.discovery`), so
listing needs no node of its own and sees the graph as it is at that moment. Hidden nodes (a name
starting with ``_``, like the CLI's own ``/_dptpu_cli_<pid>``) and their entities are left out unless
``include_hidden`` is set, as ``ros2 node list`` hides them unless ``--all``.

Lookups (:func:`find_node`, :func:`find_topic`, :func:`find_service`) wait up to ``wait_s`` seconds for
the name to appear (a node started a moment ago), then raise :class:`UnknownNameError` (a
``ValueError``: the CLI turns it into exit code 2) naming the domain and the names that do exist.
"""

from __future__ import annotations

import time

from dptpu.graph.discovery import (
    DirectoryScanner,
    GraphSnapshot,
    domain_directory,
    host_identity,
    resolve_domain_id,
    snapshot_from_entries,
)

__all__ = ["UnknownNameError", "is_hidden_node", "read_graph", "find_node", "find_topic", "find_service",
           "node_names", "format_node_info", "format_topic_info", "LOOKUP_POLL_S"]

#: Seconds between two reads of the folder while waiting for a name.
LOOKUP_POLL_S = 0.05


class UnknownNameError(ValueError):
    """A node, topic or service name that the graph does not hold."""


def is_hidden_node(name: str) -> bool:
    """True for a node whose own name (last token) starts with ``_``."""
    return str(name).rsplit("/", 1)[-1].startswith("_")


def read_graph(domain_id=None, *, include_hidden: bool = False) -> GraphSnapshot:
    """The graph of ``domain_id`` (default: ``$DPTPU_DOMAIN_ID``, ``$ROS_DOMAIN_ID``, 0) now.

    Stale announcements (dead processes) are left out; hidden nodes too unless ``include_hidden``.
    """
    domain = resolve_domain_id(domain_id)
    host, boot_id = host_identity()
    scanner = DirectoryScanner(domain_directory(domain), host=host, boot_id=boot_id, clean_stale=False)
    scanner.scan()
    entries = [entry for entry in scanner.entries
               if include_hidden or not is_hidden_node(entry.get("name", ""))]
    return snapshot_from_entries(entries, domain)


def _listing(names, what: str) -> str:
    names = sorted(set(names))
    if not names:
        return f"there are no {what}"
    shown = ", ".join(names[:20]) + (f", ... ({len(names)} in all)" if len(names) > 20 else "")
    return f"known {what}: {shown}"


def _wait_for(domain_id, wait_s: float, pick, include_hidden: bool = False):
    deadline = time.monotonic() + max(0.0, float(wait_s))
    while True:
        graph = read_graph(domain_id, include_hidden=include_hidden)
        found = pick(graph)
        if found is not None or time.monotonic() >= deadline:
            return graph, found
        time.sleep(LOOKUP_POLL_S)


def find_node(name: str, domain_id=None, *, wait_s: float = 0.0):
    """The :class:`~dptpu.graph.discovery.NodeInfo` of node ``name`` (fully qualified; ``talker`` means ``/talker``).

    Raises
    ------
    UnknownNameError
        No such node after ``wait_s`` seconds.
    """
    fqn = name if name.startswith("/") else "/" + name
    graph, node = _wait_for(domain_id, wait_s, lambda g: next(
        (n for n in g.nodes if n.fully_qualified_name == fqn), None), include_hidden=is_hidden_node(fqn))
    if node is None:
        raise UnknownNameError(f"node {fqn} is not in the graph of domain {graph.domain_id}; "
                               f"{_listing((n.fully_qualified_name for n in graph.nodes), 'nodes')}")
    return node


def find_topic(topic: str, domain_id=None, *, wait_s: float = 0.0, need_publisher: bool = True):
    """The :class:`~dptpu.graph.discovery.TopicInfo` of ``topic`` (with a publisher when ``need_publisher``).

    Raises
    ------
    UnknownNameError
        No such topic (or no publisher of it) after ``wait_s`` seconds.
    """
    def pick(graph):
        info = graph.topics.get(topic)
        return info if info is not None and (info.publisher_count or not need_publisher) else None

    graph, info = _wait_for(domain_id, wait_s, pick)
    if info is None:
        known = [name for name, t in graph.topics.items() if t.publisher_count or not need_publisher]
        what = "topics with a publisher" if need_publisher else "topics"
        problem = "has no publisher" if topic in graph.topics else "is not in the graph"
        raise UnknownNameError(f"topic {topic} {problem} of domain {graph.domain_id}; {_listing(known, what)}")
    return info


def find_service(service: str, domain_id=None, *, wait_s: float = 0.0):
    """The :class:`~dptpu.graph.discovery.ServiceInfo` of ``service``, which must have a server.

    Raises
    ------
    UnknownNameError
        No server of ``service`` after ``wait_s`` seconds.
    """
    graph, info = _wait_for(domain_id, wait_s, lambda g: (lambda s: s if s is not None and s.servers else None)(
        g.services.get(service)))
    if info is None:
        known = [name for name, s in graph.services.items() if s.servers]
        raise UnknownNameError(f"service {service} is not served in domain {graph.domain_id}; "
                               f"{_listing(known, 'services')}")
    return info


def node_names(graph: GraphSnapshot) -> list[str]:
    """Fully qualified node names, sorted (a name shared by two nodes appears twice)."""
    return sorted(node.fully_qualified_name for node in graph.nodes)


def format_node_info(node) -> str:
    """``ros2 node info``'s layout: the name, then Subscribers, Publishers, Service Servers, Service Clients."""
    lines = [node.fully_qualified_name]

    def section(title: str, items) -> None:
        lines.append(f"  {title}:")
        lines.extend(f"    {name}: {type_name}" for name, type_name in sorted(set(items)))

    section("Subscribers", ((s.topic, s.type) for s in node.subscriptions))
    section("Publishers", ((p.topic, p.type) for p in node.publishers))
    section("Service Servers", node.services)
    section("Service Clients", node.clients)
    return "\n".join(lines)


def _qos_text(qos) -> list[str]:
    if qos is None:
        return ["    (unknown)"]
    resolved = qos.resolved()
    return [f"    History (Depth): {resolved.history.name} ({resolved.depth})",
            f"    Reliability: {resolved.reliability.name}",
            f"    Durability: {resolved.durability.name}"]


def format_topic_info(info, *, verbose: bool = False) -> str:
    """``ros2 topic info [-v]``: type, publisher and subscription counts; with ``verbose`` every endpoint,
    its QoS and its counters (messages published, received, dropped, lost, malformed)."""
    lines = [f"Type: {', '.join(info.types)}", "", f"Publisher count: {info.publisher_count}"]
    if verbose:
        lines.append("")
        lines.extend(_endpoint_lines(info.publishers, "PUBLISHER"))
    lines.append(f"Subscription count: {info.subscription_count}")
    if verbose:
        lines.append("")
        lines.extend(_endpoint_lines(info.subscriptions, "SUBSCRIPTION"))
    return "\n".join(lines).rstrip("\n")


def _endpoint_lines(endpoints, kind: str) -> list[str]:
    lines = []
    for endpoint in endpoints:
        namespace, _, name = endpoint.node.rpartition("/")
        lines += [f"Node name: {name}", f"Node namespace: {namespace or '/'}", f"Topic type: {endpoint.type}",
                  f"Endpoint type: {kind}", f"GID: {endpoint.gid}", "QoS profile:", *_qos_text(endpoint.qos)]
        if endpoint.stats:
            lines.append("Statistics:")
            lines.extend(f"    {key}: {value}" for key, value in sorted(endpoint.stats.items()))
        lines.append("")
    return lines
