"""Cloud node: absolute phase -> organized point cloud and depth image.

Run: ``python -m dptpu.nodes.cloud``, or ``pkg: dptpu, exec: cloud`` in a launch file.
"""
from .node import CloudNode, main

__all__ = ["CloudNode", "main"]
