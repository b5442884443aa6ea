"""Projector node: drives the trigger box over its serial link and publishes one Trigger per pattern shown.

Modules: ``node`` (the node), ``link`` (the thread that owns the serial port), ``protocol`` (``dptpu-trigger/1``:
encode and parse), ``emulator`` (an emulator of the box on a pseudo-terminal, ``python -m
dptpu.nodes.projector.emulator``).

Run: ``python -m dptpu.nodes.projector``, or ``pkg: dptpu, exec: projector`` in a launch file.
"""
from .node import ProjectorNode, main

__all__ = ["ProjectorNode", "main"]
