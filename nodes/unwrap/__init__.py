"""Unwrap node: wrapped phase maps -> absolute phase (temporal phase unwrapping, optionally DP-TPU).

Run: ``python -m dptpu.nodes.unwrap``, or ``pkg: dptpu, exec: unwrap`` in a launch file.
"""
from typing import TYPE_CHECKING

from dptpu.nodes.node_start import node_exports

if TYPE_CHECKING:
    from .node import UnwrapNode, main

__all__ = ["UnwrapNode", "main"]
__getattr__ = node_exports(__name__, __all__)  # the node module on first use: a quiet Ctrl-C while it imports
