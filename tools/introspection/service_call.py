"""``dptpu service call``: one request to a served service from the CLI's node, and its response."""

from __future__ import annotations

from collections.abc import Callable

from .cli_node import cli_node
from .graph_view import find_service

__all__ = ["call_service"]


def call_service(service: str, srv_type, request, domain_id: int, *, wait_s: float, timeout_s: float,
                 before_call: Callable[[], None] | None = None):
    """The response of ``service`` to ``request``.

    Parameters
    ----------
    service : str
        Absolute service name; it must be served with type ``srv_type`` (``ValueError`` otherwise).
    srv_type : type
        The service class (:func:`~.cli_names.service_class`).
    request : Message
        A ``srv_type.Request``.
    domain_id : int
    wait_s : float
        Seconds to wait for the service to appear in the graph (:class:`~.graph_view.UnknownNameError` after).
    timeout_s : float
        Seconds to wait for the server to be reachable, then for its response (``TimeoutError`` after).
    before_call : callable, optional
        Called once the server is reachable, just before the request is sent.

    Raises
    ------
    TimeoutError
        The server did not become reachable, or did not answer, within ``timeout_s``.
    ServiceCallError
        The server failed to handle the request.
    """
    info = find_service(service, domain_id, wait_s=wait_s)
    if srv_type.TYPE_NAME not in info.types:
        raise ValueError(f"service {service} has type {', '.join(info.types)}; got {srv_type.TYPE_NAME}")
    with cli_node(domain_id) as (node, _executor):
        client = node.create_client(srv_type, service)
        if not client.wait_for_service(timeout_sec=timeout_s):
            raise TimeoutError(f"service {service} did not become available within {timeout_s:g} s")
        if before_call is not None:
            before_call()
        return client.call(request, timeout_sec=timeout_s)
