"""The names a user gives ``dptpu node|topic|service``, made absolute and checked, and the types behind them.

Relative names are expanded as ``ros2`` expands them for its CLI node: in the root namespace. The message class of
a topic and the class of a service type come from the registries (:mod:`dptpu.messages.registry`,
:mod:`dptpu.graph.interfaces`); a type this build does not know is a ``ValueError`` that says what still works.
"""

from __future__ import annotations

import re

from dptpu.graph.interfaces import lookup_service
from dptpu.graph.names import expand_topic_name
from dptpu.messages.registry import is_registered, lookup

__all__ = ["topic_name", "service_name", "node_name", "topic_message_class", "service_class"]

#: The node name names are expanded for (the CLI's node lives in the root namespace).
_EXPANDING_NODE = "_dptpu_cli"
_NODE_NAME = re.compile(r"^/?[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*$")
_SERVICE_TYPE = re.compile(r"^([a-z][a-z0-9_]*)/(?:srv/)?([A-Z][A-Za-z0-9]*)$")


def topic_name(name: str) -> str:
    """The absolute topic name of ``name`` (``chatter`` -> ``/chatter``); ``ValueError`` when malformed."""
    return expand_topic_name(name, _EXPANDING_NODE, "/")


def service_name(name: str) -> str:
    """The absolute service name of ``name``; ``ValueError`` when malformed."""
    return expand_topic_name(name, _EXPANDING_NODE, "/", is_service=True)


def node_name(name: str) -> str:
    """The fully qualified node name of ``name`` (``talker`` -> ``/talker``); ``ValueError`` when malformed."""
    if not isinstance(name, str) or not _NODE_NAME.match(name):
        raise ValueError(f"node name must look like /name or /namespace/name; got {name!r}")
    return name if name.startswith("/") else "/" + name


def topic_message_class(info, *, required: bool):
    """The registered class of a topic's single type; None (raw) when unknown and not ``required``.

    Parameters
    ----------
    info : TopicInfo
        From :func:`~.graph_view.find_topic`.
    required : bool
        Whether an unknown type is an error (``echo`` decodes; ``hz`` and ``bw`` count raw frames).
    """
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


def service_class(type_name: str):
    """The service class of ``package/srv/Name`` (or ``package/Name``); ``ValueError`` when unknown."""
    match = _SERVICE_TYPE.match(type_name or "")
    if match is None:
        raise ValueError(f"service type must look like package/srv/Name (e.g. std_srvs/srv/Trigger); "
                         f"got {type_name!r}")
    full = f"{match.group(1)}/srv/{match.group(2)}"
    try:
        return lookup_service(full)
    except KeyError as exc:
        raise ValueError(exc.args[0]) from None
