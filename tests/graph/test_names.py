"""ROS 2 names: expansion, validation errors, remapping rules."""

from __future__ import annotations

import pytest

from dptpu.graph import InvalidNamespaceException, InvalidNodeNameException, InvalidTopicNameException, Node
from dptpu.graph.exceptions import ROSArgumentsError
from dptpu.graph.names import (
    expand_topic_name,
    normalize_namespace,
    parse_remap_rule,
    remap_name,
    remap_namespace,
    remap_node_name,
    validate_node_name,
)


@pytest.mark.parametrize("name, expected", [
    ("image", "/rig/image"),
    ("/abs/image", "/abs/image"),
    ("~", "/rig/cam"),
    ("~/status", "/rig/cam/status"),
    ("{node}/info", "/rig/cam/info"),
    ("{ns}/info", "/rig/info"),
])
def test_expand_topic_name_in_namespace(name, expected):
    assert expand_topic_name(name, "cam", "/rig") == expected


def test_expand_topic_name_in_root_namespace():
    assert expand_topic_name("image", "cam", "/") == "/image"
    assert expand_topic_name("~/status", "cam", "/") == "/cam/status"


@pytest.mark.parametrize("name, reason", [
    ("", "must not be empty"),
    ("a//b", "must not contain '//'"),
    ("a/", "must not end with '/'"),
    ("2d/points", "token '2d' must hold only letters"),
    ("a b", "token 'a b'"),
    ("a/~b", "'~' may only appear"),
    ("{what}/x", "unknown substitution {what}"),
])
def test_invalid_topic_names_are_refused_with_the_reason(name, reason):
    with pytest.raises(InvalidTopicNameException, match=reason):
        expand_topic_name(name, "cam", "/rig")


def test_node_name_and_namespace_rules():
    assert validate_node_name("phase_node") == "phase_node"
    with pytest.raises(InvalidNodeNameException, match="must not start with a digit"):
        validate_node_name("3d_node")
    with pytest.raises(InvalidNodeNameException, match="must not be empty"):
        validate_node_name("")
    assert normalize_namespace(None) == "/" and normalize_namespace("scanner") == "/scanner"
    with pytest.raises(InvalidNamespaceException, match="must not contain '//' or end with '/'"):
        normalize_namespace("/scanner/")


def test_remap_rules_match_expanded_names_and_first_rule_wins():
    rules = [parse_remap_rule("image:=/camera/image_raw"), parse_remap_rule("image:=/other"),
             parse_remap_rule("talker:out:=/only_talker"), parse_remap_rule("__node:=renamed"),
             parse_remap_rule("__ns:=/moved")]
    assert remap_name(rules, "/rig/image", "cam", "/rig") == "/camera/image_raw"
    assert remap_name(rules, "/image", "cam", "/rig") == "/image"  # rule 'image' expands to /rig/image here
    assert remap_name(rules, "/rig/out", "cam", "/rig") == "/rig/out"  # node-specific rule, other node
    assert remap_name(rules, "/out", "talker", "/") == "/only_talker"
    assert remap_node_name(rules, "cam") == "renamed"
    assert remap_namespace(rules, "cam", "/") == "/moved"


@pytest.mark.parametrize("text, message", [
    ("image", "must look like 'from:=to'"),
    ("image:=", "empty replacement"),
    ("__node:=9lives", "must not start with a digit"),
    ("__foo:=x", "unknown special name '__foo'"),
    ("a b:=c", "token 'a b'"),
])
def test_bad_remap_rules_are_refused(text, message):
    with pytest.raises(ROSArgumentsError, match=message):
        parse_remap_rule(text)


def test_node_resolves_names_with_its_remaps(make_context):
    context = make_context(["prog", "--ros-args", "-r", "__ns:=/scanner", "-r", "raw:=/camera/image_raw"])
    node = Node("phase", context=context, cli_args=["--ros-args", "-r", "__node:=phase_node"])
    assert node.get_fully_qualified_name() == "/scanner/phase_node"
    assert node.resolve_topic_name("raw") == "/camera/image_raw"
    assert node.resolve_topic_name("~/status") == "/scanner/phase_node/status"
    assert node.resolve_topic_name("raw", only_expand=True) == "/scanner/raw"
    assert node.get_logger().name == "scanner.phase_node"
