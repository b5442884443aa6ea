"""The shipped parameter files reach their nodes under any namespace (a rig included under ``push_ros_namespace``).

A node key ``projector:`` in a ROS 2 parameter file means ``/projector`` only (rcl prepends the ``/``), so a rig
launched inside ``group: [push_ros_namespace: {namespace: /robot1}, include: ...]`` would start ``/robot1/projector``
without its file's settings (the sim rig's projector then opened /dev/ttyACM0 instead of ``loop://``). The keys are
written ``/**/projector:``, which ROS 2 and ``dptpu.graph.param_files`` both match in every namespace.
"""
from __future__ import annotations

import pytest

from dptpu.graph.param_files import overrides_for_node, read_params_file
from dptpu.tools.launch import ParameterFile, load_launch_file
from dptpu.tools.launch.installed import installed_launch_dir, installed_launch_files


@pytest.mark.parametrize("rig", installed_launch_files())
@pytest.mark.parametrize("namespace", ["/robot1", "/cell/arm2"])
def test_each_node_gets_the_same_file_parameters_in_a_namespace(rig, namespace):
    plan = load_launch_file(str(installed_launch_dir() / rig), {})
    checked = 0
    for node in plan.nodes:
        sources = [read_params_file(p.path) for p in node.parameters if isinstance(p, ParameterFile)]
        if not sources:
            continue
        name = node.name or node.label
        at_root = overrides_for_node(sources, f"/{name}")
        assert at_root, f"{rig}: no parameter of {[s.origin for s in sources]} reaches /{name}"
        assert overrides_for_node(sources, f"{namespace}/{name}") == at_root, f"{rig}: {name} in {namespace}"
        checked += 1
    assert checked >= 2  # every rig gives phase and cloud their pipeline.yaml
