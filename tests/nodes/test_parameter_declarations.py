"""Every scanner node declares each parameter through ParameterRules: settable (checked, applied) or read-only.

A parameter declared with ``declare_parameter`` directly would take any ``param set`` and change nothing (issue 18:
``param set /cloud frame_id ...`` "succeeded" and every later cloud kept the old frame).
"""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

NODES = Path(__file__).resolve().parents[2] / "nodes"
NODE_MODULES = sorted(NODES.glob("*/node.py"))


def test_every_scanner_node_module_is_checked():
    assert {p.parent.name for p in NODE_MODULES} >= {"camera", "cloud", "phase", "projector", "ros2_bridge",
                                                      "scan_monitor", "sim", "unwrap", "viewer"}


@pytest.mark.parametrize("module", NODE_MODULES, ids=lambda p: p.parent.name)
def test_parameters_are_declared_settable_or_read_only(module):
    tree = ast.parse(module.read_text(encoding="utf-8"))
    direct = [f"{module.parent.name}/node.py:{node.lineno}" for node in ast.walk(tree)
              if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
              and node.func.attr in ("declare_parameter", "declare_parameters")]
    assert direct == [], "declare through ParameterRules.settable / read_only instead: " + ", ".join(direct)
    rules = [node for node in ast.walk(tree) if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
             and node.func.attr in ("settable", "read_only")]
    assert rules, f"{module.parent.name}/node.py declares no parameter through ParameterRules"
