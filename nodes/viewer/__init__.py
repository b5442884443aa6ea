"""Viewer node: the point cloud in a browser (HTTP + WebSocket, three.js).

Modules: ``node`` (the node, HTTP server, cloud message), ``websocket`` (the server side of RFC 6455); ``static/``
(the page, its script and the three.js bundle).

Run: ``python -m dptpu.nodes.viewer``, or ``pkg: dptpu, exec: viewer`` in a launch file.
"""
from typing import TYPE_CHECKING

from dptpu.nodes.node_start import node_exports

if TYPE_CHECKING:
    from .node import ViewerNode, main

__all__ = ["ViewerNode", "main"]
__getattr__ = node_exports(__name__, __all__)  # the node module on first use: a quiet Ctrl-C while it imports
