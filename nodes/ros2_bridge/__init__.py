"""ROS 2 bridge: the scanner's topics and start service on a ROS 2 (Cyclone DDS) domain.

Modules: ``node`` (the node), ``ros2_idl`` (ROS 2's DDS types and conversions), ``ros2_qos`` (ROS 2's QoS
profiles, the Cyclone configuration).

Run: ``python -m dptpu.nodes.ros2_bridge``, or ``pkg: dptpu, exec: ros2_bridge`` in a launch file.
"""
from typing import TYPE_CHECKING

from dptpu.nodes.node_start import node_exports

if TYPE_CHECKING:
    from .node import Ros2BridgeNode, main

__all__ = ["Ros2BridgeNode", "main"]
__getattr__ = node_exports(__name__, __all__)  # the node module on first use: a quiet Ctrl-C while it imports
