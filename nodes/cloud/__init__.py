"""Cloud node: absolute phase -> organized point cloud and depth image.

Run: ``python -m dptpu.nodes.cloud``, or ``pkg: dptpu, exec: cloud`` in a launch file.
"""
from typing import TYPE_CHECKING

from dptpu.nodes.node_start import node_exports

if TYPE_CHECKING:
    from .node import CloudNode, main

__all__ = ["CloudNode", "main"]
__getattr__ = node_exports(__name__, __all__)  # the node module on first use: a quiet Ctrl-C while it imports
