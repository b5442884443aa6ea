"""The short-lived, hidden node through which the introspection CLI subscribes and calls services.

:func:`cli_node` gives a node named ``_dptpu_cli_<pid>`` in a private :class:`~dptpu.graph.Context`
of the requested domain (so it never touches the process's default context), without parameter
services, and shuts the context down on exit: the announcement disappears and every socket closes,
also on Ctrl-C. The leading ``_`` hides it from ``dptpu node list`` (like ``ros2``'s ``_ros2cli_``
nodes).

:func:`subscription_qos` picks the QoS the CLI subscribes with, from the publishers' offered QoS, so
the subscription connects to all of them (ROS 2's request-versus-offered rules).
"""

from __future__ import annotations

import os
from contextlib import contextmanager

from dptpu.graph.context import Context
from dptpu.graph.executors import SingleThreadedExecutor
from dptpu.graph.node import Node
from dptpu.graph.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

__all__ = ["cli_node", "subscription_qos", "CLI_NODE_PREFIX"]

#: Prefix of the CLI's node names (hidden: starts with ``_``).
CLI_NODE_PREFIX = "_dptpu_cli_"


@contextmanager
def cli_node(domain_id=None, *, suffix: str = ""):
    """Yield ``(node, executor)``: a hidden node of ``domain_id`` and a single-threaded executor holding it.

    Parameters
    ----------
    domain_id : int, optional
        Default: ``$DPTPU_DOMAIN_ID``, ``$ROS_DOMAIN_ID``, 0.
    suffix : str
        Appended to the node name (letters, digits, ``_``).
    """
    context = Context()
    context.init([], domain_id=domain_id)
    try:
        node = Node(f"{CLI_NODE_PREFIX}{os.getpid()}{suffix}", context=context, start_parameter_services=False,
                    use_global_arguments=False)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        yield node, executor
    finally:
        context.try_shutdown()


def subscription_qos(offered, *, depth: int = 10) -> QoSProfile:
    """A QoS that connects to every publisher offering one of ``offered`` (QoSProfile or None = unknown).

    KEEP_LAST ``depth``; RELIABLE only when every publisher offers RELIABLE, else BEST_EFFORT;
    TRANSIENT_LOCAL only when every publisher offers it (so ``echo`` shows a latched message), else
    VOLATILE.
    """
    if isinstance(depth, bool) or not isinstance(depth, int) or depth < 1:
        raise ValueError(f"depth must be an int >= 1; got {depth!r}")
    known = [qos.resolved() for qos in offered if qos is not None]
    reliable = bool(known) and all(q.reliability == ReliabilityPolicy.RELIABLE for q in known)
    transient = bool(known) and all(q.durability == DurabilityPolicy.TRANSIENT_LOCAL for q in known)
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                      reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL if transient else DurabilityPolicy.VOLATILE)
