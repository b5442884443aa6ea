"""Projector node: drives the trigger box over its serial link and publishes one Trigger per pattern shown.

Modules: ``node`` (the node), ``link`` (the thread that owns the serial port), ``protocol`` (``dptpu-trigger/1``:
encode and parse), ``emulator`` (an emulator of the box on a pseudo-terminal, ``python -m
dptpu.nodes.projector.emulator``).

Run: ``python -m dptpu.nodes.projector``, or ``pkg: dptpu, exec: projector`` in a launch file.
"""
from typing import TYPE_CHECKING

from dptpu.nodes.node_start import node_exports

if TYPE_CHECKING:
    from .node import ProjectorNode, main

__all__ = ["ProjectorNode", "main"]
__getattr__ = node_exports(__name__, __all__)  # the node module on first use: a quiet Ctrl-C while it imports
