"""Scan monitor: follows each scan through the graph, grades it against the twin's ground truth, writes PLYs.

Modules: ``node`` (the node), ``scan_metrics`` (the figures of one scan).

Run: ``python -m dptpu.nodes.scan_monitor``, or ``pkg: dptpu, exec: scan_monitor`` in a launch file.
"""
from .node import ScanMonitorNode, main

__all__ = ["ScanMonitorNode", "main"]
