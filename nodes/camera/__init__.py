"""Camera node: a GenICam camera triggered per pattern, each frame published with the Trigger it answers.

Modules: ``node`` (the node), ``genicam_acquisition`` (the acquisition thread), ``genicam_device`` (one camera
through harvesters), ``genicam_producers`` (finding GenTL producer ``.cti`` files).

Run: ``python -m dptpu.nodes.camera``, or ``pkg: dptpu, exec: camera`` in a launch file.
"""
from typing import TYPE_CHECKING

from dptpu.nodes.node_start import node_exports

if TYPE_CHECKING:
    from .node import CameraNode, main

__all__ = ["CameraNode", "main"]
__getattr__ = node_exports(__name__, __all__)  # the node module on first use: a quiet Ctrl-C while it imports
