"""``python -m dptpu.nodes.ros2_bridge [--ros-args ...]``."""
from dptpu.nodes.node_start import run_node_module

run_node_module("dptpu.nodes.ros2_bridge")
