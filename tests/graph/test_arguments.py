"""The ROS 2 command line: --ros-args sections, flags, unknown flags, non-ROS arguments."""

from __future__ import annotations

import pytest

from dptpu.graph import LoggingSeverity, UnknownROSArgsError, remove_ros_args
from dptpu.graph.arguments import parse_ros_arguments
from dptpu.graph.exceptions import ROSArgumentsError


def test_ros_section_is_parsed_and_the_rest_kept():
    args = ["prog", "--fast", "--ros-args", "-r", "a:=b", "--remap", "__node:=n", "-p", "gain:=2.5",
            "--param", "ids:=[1, 2]", "--log-level", "debug", "--log-level", "cam:=warn", "--disable-rosout-logs",
            "--", "--out", "x.ply"]
    parsed = parse_ros_arguments(args)
    assert [(r.match, r.replacement) for r in parsed.remap_rules] == [("a", "b"), ("__node", "n")]
    assert [s.entries for s in parsed.parameter_sources] == [(("/**", {"gain": 2.5}),), (("/**", {"ids": [1, 2]}),)]
    assert parsed.log_levels == {"": LoggingSeverity.DEBUG, "cam": LoggingSeverity.WARN}
    assert parsed.non_ros_args == ["prog", "--fast", "--out", "x.ply"]
    assert remove_ros_args(args) == ["prog", "--fast", "--out", "x.ply"]


def test_param_values_are_typed_like_yaml():
    def value(text):
        return parse_ros_arguments(["--ros-args", "-p", f"v:={text}"]).parameter_sources[0].entries[0][1]["v"]

    assert [value("3"), value("3.0"), value("true"), value("hello"), value("[a, b]"), value("")] == \
        [3, 3.0, True, "hello", ["a", "b"], ""]
    assert value("{a: 1}") == "{a: 1}"  # a map is no parameter value: kept as text


def test_unknown_and_incomplete_flags_are_errors():
    with pytest.raises(UnknownROSArgsError, match="unknown ROS argument '--frobnicate'"):
        parse_ros_arguments(["--ros-args", "--frobnicate"])
    with pytest.raises(ROSArgumentsError, match="-p needs a value"):
        parse_ros_arguments(["--ros-args", "-p"])
    with pytest.raises(ROSArgumentsError, match="log level must be one of"):
        parse_ros_arguments(["--ros-args", "--log-level", "loud"])
    assert parse_ros_arguments(["prog", "--frobnicate"]).non_ros_args == ["prog", "--frobnicate"]
