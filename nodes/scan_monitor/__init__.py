"""Scan monitor: follows each scan through the graph, grades it against the twin's ground truth, writes PLYs.

Modules: ``node`` (the node), ``scan_metrics`` (the figures of one scan).

Run: ``python -m dptpu.nodes.scan_monitor``, or ``pkg: dptpu, exec: scan_monitor`` in a launch file.
"""
from typing import TYPE_CHECKING

from dptpu.nodes.node_start import node_exports

if TYPE_CHECKING:
    from .node import ScanMonitorNode, main

__all__ = ["ScanMonitorNode", "main"]
__getattr__ = node_exports(__name__, __all__)  # the node module on first use: a quiet Ctrl-C while it imports
