"""Which endpoints a subscription or a client should be connected to, read from the graph's announcements.

Pure logic over announcement entries (no sockets): after each scan the runtime's I/O thread
(:mod:`dptpu.graph.runtime`) asks for the endpoints each subscription and each client wants, then connects and
disconnects their sockets to match. A publisher the subscription's known-publisher policy refuses
(:mod:`dptpu.graph.known_publishers`), a publisher of another type or of an incompatible QoS, or a server of another
type, is skipped with one warning per peer on the entity's node logger.
"""

from __future__ import annotations

from collections.abc import Callable

from .known_publishers import select_publishers
from .qos import QoSProfile, qos_compatibility
from .transport import TransportConfig, choose_endpoint

__all__ = ["index_endpoints", "wanted_publishers", "wanted_servers"]


def index_endpoints(entries: list[dict]) -> tuple[dict[str, list], dict[str, list]]:
    """``(publishers, servers)`` of the announcements: topic -> ``[(entry, publisher)]`` and service name ->
    ``[(entry, server)]``; malformed items are left out."""
    publishers: dict[str, list] = {}
    servers: dict[str, list] = {}
    for entry in entries:
        for pub in entry.get("publishers", []):
            if isinstance(pub, dict) and isinstance(pub.get("topic"), str):
                publishers.setdefault(pub["topic"], []).append((entry, pub))
        for srv in entry.get("services", []):
            if isinstance(srv, dict) and isinstance(srv.get("name"), str):
                servers.setdefault(srv["name"], []).append((entry, srv))
    return publishers, servers


def wanted_publishers(sub, candidates: list, *, same_host: Callable[[dict], bool],
                      transport: TransportConfig) -> dict[str, tuple]:
    """``endpoint -> (publisher gid, CURVE public key or None)`` of the publishers ``sub`` should hear.

    ``candidates`` are the ``(entry, publisher)`` pairs of its topic; ``same_host(entry)`` says whether the entry
    is of this host (ipc endpoints are reachable).
    """
    wanted: dict[str, tuple] = {}
    candidates, refused = select_publishers(candidates, getattr(sub, "known_publishers", None),
                                             set(sub._connected.values()))
    for entry, pub, reason in refused:
        gid = str(pub.get("gid", ""))
        if gid not in sub._warned:
            sub._warned.add(gid)
            sub._node.get_logger().warning(
                f"refusing the publisher of {sub.topic_name} of node {entry.get('fqn')} (pid {entry.get('pid')}): "
                f"{reason}")
    for entry, pub in candidates:
        gid = str(pub.get("gid", ""))
        problem = None
        if sub.msg_type is not None and pub.get("type") != sub.msg_type.TYPE_NAME:
            problem = f"it publishes {pub.get('type')}, the subscription expects {sub.msg_type.TYPE_NAME}"
        else:
            try:
                problem = qos_compatibility(QoSProfile.from_dict(pub.get("qos")), sub.qos_profile)
            except ValueError as exc:
                problem = f"its QoS is unreadable ({exc})"
        if problem:
            if gid not in sub._warned:
                sub._warned.add(gid)
                sub._node.get_logger().warning(
                    f"not connecting subscription on {sub.topic_name} to the publisher of node "
                    f"{entry.get('fqn')}: {problem}")
            continue
        endpoint = choose_endpoint(pub.get("endpoints"), same_host=same_host(entry), config=transport)
        if endpoint is not None:
            wanted[endpoint] = (gid, entry.get("curve_public_key"))
    return wanted


def wanted_servers(client, candidates: list, *, same_host: Callable[[dict], bool],
                   transport: TransportConfig) -> dict[str, tuple]:
    """``endpoint -> (server gid, CURVE public key or None)`` of the servers ``client`` should reach.

    ``candidates`` are the ``(entry, server)`` pairs of its service name.
    """
    wanted: dict[str, tuple] = {}
    for entry, srv in candidates:
        if srv.get("type") != client.srv_type.TYPE_NAME:
            gid = str(entry.get("gid"))
            if ("type", gid) not in getattr(client, "_warned", set()):
                client._warned = getattr(client, "_warned", set()) | {("type", gid)}
                client._node.get_logger().warning(
                    f"not connecting client of {client.srv_name} to node {entry.get('fqn')}: it serves type "
                    f"{srv.get('type')}, the client expects {client.srv_type.TYPE_NAME}")
            continue
        endpoint = choose_endpoint(entry.get("service_endpoints"), same_host=same_host(entry), config=transport)
        if endpoint is not None:
            wanted[endpoint] = (str(entry.get("gid")), entry.get("curve_public_key"))
    return wanted
