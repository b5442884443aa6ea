"""``python -m dptpu.nodes.projector [--ros-args ...]``."""
from dptpu.nodes.node_start import run_node_module

run_node_module("dptpu.nodes.projector")
