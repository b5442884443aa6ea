"""Sim node: the digital twin in place of projector and camera, publishing rendered fringe frames per scan.

Modules: ``node`` (the node), ``source`` (the scenes it replays or renders).

Run: ``python -m dptpu.nodes.sim``, or ``pkg: dptpu, exec: sim`` in a launch file.
"""
from typing import TYPE_CHECKING

from dptpu.nodes.node_start import node_exports

if TYPE_CHECKING:
    from .node import SimNode, main

__all__ = ["SimNode", "main"]
__getattr__ = node_exports(__name__, __all__)  # the node module on first use: a quiet Ctrl-C while it imports
