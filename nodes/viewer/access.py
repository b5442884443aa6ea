"""Who may talk to the viewer's server: the ``Host`` and ``Origin`` a request must carry.

The server binds localhost by default, but a page of any other site open in the same browser can still reach it:
by DNS rebinding (a foreign name that resolves to 127.0.0.1; its requests carry that name as ``Host``) or by
opening ``ws://127.0.0.1:PORT/ws`` from its own page (Cross-Site WebSocket Hijacking: the browser sends that
page's ``Origin``). So every request must name the server's own address as ``Host``, and a WebSocket upgrade that
carries an ``Origin`` must come from the viewer's own page, ``http://`` + one of those addresses (RFC 6455
section 10.2: servers that are not meant for every site check ``Origin``). A client without ``Origin`` is not a
browser page (browsers always send it on WebSocket upgrades) and is let through.
"""

from __future__ import annotations

import ipaddress
import socket

__all__ = ["allowed_hosts", "host_problem", "origin_problem"]

_LOOPBACK_NAMES = ("localhost", "127.0.0.1", "[::1]")


def allowed_hosts(host: str, port: int) -> frozenset[str]:
    """The ``Host`` values of requests meant for a server bound to ``host``:``port``, lower case, with the port.

    A loopback address adds ``localhost``, ``127.0.0.1`` and ``[::1]``; a wildcard address (``0.0.0.0``, ``::``,
    reached from anywhere) adds those, the machine's name, its fully qualified name and the IPv4 addresses the
    name resolves to.
    """
    names = {_bracketed(host)}
    if _is_loopback(host) or _is_wildcard(host):
        names.update(_LOOPBACK_NAMES)
    if _is_wildcard(host):
        names.update({socket.gethostname(), socket.getfqdn()})
        try:  # the machine's own addresses, as a browser on another machine types them
            names.update(socket.gethostbyname_ex(socket.gethostname())[2])
        except OSError:
            pass
    return frozenset(f"{name.lower()}:{port}" for name in names if name)


def host_problem(host_header: str | None, allowed: frozenset[str]) -> str | None:
    """Why a request's ``Host`` is refused (None when it is one of ``allowed``)."""
    if not host_header:
        return "a request without a Host header"
    if host_header.strip().lower() not in allowed:
        return f"Host {host_header.strip()!r} is not this server ({', '.join(sorted(allowed))})"
    return None


def origin_problem(origin: str | None, allowed: frozenset[str]) -> str | None:
    """Why a WebSocket upgrade's ``Origin`` is refused (None when absent or the viewer's own page)."""
    if origin is None:
        return None
    value = origin.strip().lower()
    if not value.startswith("http://") or value[len("http://"):] not in allowed:
        return f"Origin {origin.strip()!r} is not the viewer's page (http:// + one of {', '.join(sorted(allowed))})"
    return None


def _bracketed(host: str) -> str:
    return f"[{host}]" if ":" in host and not host.startswith("[") else host


def _is_loopback(host: str) -> bool:
    if host.lower() == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def _is_wildcard(host: str) -> bool:
    try:
        return ipaddress.ip_address(host.strip("[]")).is_unspecified
    except ValueError:
        return host == ""
