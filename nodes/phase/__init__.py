"""Phase node: fringe frames of each scan -> wrapped phase maps.

Modules: ``node`` (the node), ``sequence_assembler`` (frames collected by ``sequence_id``: pure logic).

Run: ``python -m dptpu.nodes.phase``, or ``pkg: dptpu, exec: phase`` in a launch file.
"""
from typing import TYPE_CHECKING

from dptpu.nodes.node_start import node_exports

if TYPE_CHECKING:
    from .node import PhaseNode, main

__all__ = ["PhaseNode", "main"]
__getattr__ = node_exports(__name__, __all__)  # the node module on first use: a quiet Ctrl-C while it imports
