"""Unwrap node: wrapped phase maps -> absolute phase (temporal phase unwrapping, optionally DP-TPU).

Run: ``python -m dptpu.nodes.unwrap``, or ``pkg: dptpu, exec: unwrap`` in a launch file.
"""
from .node import UnwrapNode, main

__all__ = ["UnwrapNode", "main"]
