"""The ``main()`` every scanner node shares: init, build the node, spin until Ctrl-C or SIGTERM, clean up.

A node whose parameters are wrong cannot start: its constructor raises ``ValueError`` (or ``OSError`` for a
file it cannot open, ``ImportError`` for an optional part that is not installed) and the process prints one line
naming the node and the problem and exits with code 2, which ``dptpu launch`` reports; it never shows a traceback.
"""
from __future__ import annotations

import sys
from typing import Callable

import dptpu.graph as rclpy
from dptpu.graph import ExternalShutdownException
from dptpu.graph.node import Node

__all__ = ["run_node", "SETUP_ERRORS"]

#: What a node's constructor raises for bad parameters, unreadable files or missing optional parts (exit code 2).
SETUP_ERRORS = (ValueError, OSError, ImportError)


def run_node(name: str, make_node: Callable[[], Node], argv=None) -> int:
    """Run one node in this process until Ctrl-C, SIGTERM or shutdown; return the process exit code.

    Parameters
    ----------
    name : str
        The node's short name, for the error line (``cloud: error: ...``).
    make_node : callable
        Builds the node (its class); called after ``rclpy.init`` so it sees ``--ros-args``.
    argv : list of str, optional
        The command line (default ``sys.argv``), with ``--ros-args -p name:=value -r from:=to ...``.

    Returns
    -------
    int
        0 after a clean stop, 2 when the node could not start.
    """
    rclpy.init(args=sys.argv if argv is None else argv)
    try:
        node = make_node()
    except SETUP_ERRORS as exc:
        print(f"{name}: error: {exc}", file=sys.stderr)
        rclpy.try_shutdown()
        return 2
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0
