"""Viewer node: the point cloud in a browser (HTTP + WebSocket, three.js).

Modules: ``node`` (the node, HTTP server, cloud message), ``websocket`` (the server side of RFC 6455); ``static/``
(the page, its script and the three.js bundle).

Run: ``python -m dptpu.nodes.viewer``, or ``pkg: dptpu, exec: viewer`` in a launch file.
"""
from .node import ViewerNode, main

__all__ = ["ViewerNode", "main"]
