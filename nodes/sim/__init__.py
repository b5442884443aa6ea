"""Sim node: the digital twin in place of projector and camera, publishing rendered fringe frames per scan.

Modules: ``node`` (the node), ``source`` (the scenes it replays or renders).

Run: ``python -m dptpu.nodes.sim``, or ``pkg: dptpu, exec: sim`` in a launch file.
"""
from .node import SimNode, main

__all__ = ["SimNode", "main"]
