"""Phase node: fringe frames of each scan -> wrapped phase maps.

Modules: ``node`` (the node), ``sequence_assembler`` (frames collected by ``sequence_id``: pure logic).

Run: ``python -m dptpu.nodes.phase``, or ``pkg: dptpu, exec: phase`` in a launch file.
"""
from .node import PhaseNode, main

__all__ = ["PhaseNode", "main"]
