"""Parameters: ROS 2 YAML files and command-line overrides with ROS 2 precedence, types, ranges, callbacks."""

from __future__ import annotations

import textwrap

import pytest

from dptpu.graph import (
    IntegerRange,
    InvalidParameterTypeException,
    InvalidParameterValueException,
    Node,
    Parameter,
    ParameterDescriptor,
    ParameterNotDeclaredException,
    ROSArgumentsError,
    SetParametersResult,
)
from dptpu.graph.param_files import node_pattern_matches, parse_params_yaml, read_params_file


def _write(path, text):
    path.write_text(textwrap.dedent(text))
    return str(path)


def test_yaml_and_command_line_overrides_follow_ros2_precedence(spawn, tmp_path):
    first = _write(tmp_path / "first.yaml", """\
        /**:
          ros__parameters:
            a: 1
            b: 1
            c: wildcard
        param_node:
          ros__parameters:
            a: 2
            nested: {x: 5}
            names: [p, q]
        other_node:
          ros__parameters: {a: 99}
        """)
    second = _write(tmp_path / "second.yaml", """\
        /param_node:
          ros__parameters: {c: second_file}
        """)
    node = spawn("param_node", "--ros-args", "--params-file", first, "-p", "b:=3", "-p", "c:=cli",
                 "--params-file", second)
    params = node.wait_event("ready")["params"]
    assert params == {"a": 2,            # node entry beats the /** wildcard of the same file
                      "b": 3,            # -p beats the earlier file
                      "c": "second_file",  # a later source beats an earlier -p
                      "nested.x": 5,     # nested maps become dotted names
                      "names": ["p", "q"],
                      "rate_hz": 1.0}    # not overridden: the declared default


def test_parameter_overrides_argument_beats_command_line(make_context):
    context = make_context(["prog", "--ros-args", "-p", "gain:=2.0", "-p", "label:=cli"])
    node = Node("tuner", context=context, parameter_overrides=[Parameter("gain", value=3.5)],
                cli_args=["--ros-args", "-p", "label:=node_args"])
    assert node.declare_parameter("gain", 1.0).value == 3.5                 # parameter_overrides win
    assert node.declare_parameter("label", "default").value == "node_args"  # node args beat global args
    assert node.declare_parameter("untouched", 4).value == 4


def test_override_of_wrong_type_is_refused_naming_its_source(make_context):
    node = Node("typed", context=make_context(["prog", "--ros-args", "-p", "rate_hz:=10"]))
    with pytest.raises(InvalidParameterTypeException, match=r"is of type DOUBLE, setting it to INTEGER.*-p "
                                                            r"rate_hz:=10"):
        node.declare_parameter("rate_hz", 1.0)


def test_set_parameters_checks_type_range_read_only_and_callbacks(context):
    node = Node("checked", context=context)
    node.declare_parameter("steps", 12, ParameterDescriptor(integer_range=[IntegerRange(from_value=3, to_value=24,
                                                                                        step=3)]))
    node.declare_parameter("serial", "A1", ParameterDescriptor(read_only=True))
    node.declare_parameter("exposure_us", 1000.0)
    node.add_on_set_parameters_callback(
        lambda ps: SetParametersResult(successful=all(p.name != "exposure_us" or p.value < 5e4 for p in ps),
                                       reason="exposure_us must be < 50000"))
    results = node.set_parameters([Parameter("steps", value=9), Parameter("steps", value=10),
                                   Parameter("steps", value=30), Parameter("serial", value="B2"),
                                   Parameter("exposure_us", value=1e5), Parameter("exposure_us", value=2000)])
    assert [r.successful for r in results] == [True, False, False, False, False, False]
    assert "not on a step of 3" in results[1].reason
    assert "outside the range [3, 24]" in results[2].reason
    assert results[3].reason == "Trying to set a read-only parameter: serial"
    assert results[4].reason == "exposure_us must be < 50000"
    assert "is of type DOUBLE, setting it to INTEGER" in results[5].reason
    assert node.get_parameter("steps").value == 9
    assert node.get_parameter("exposure_us").value == 1000.0
    with pytest.raises(ParameterNotDeclaredException, match="'nope' has not been declared"):
        node.set_parameters([Parameter("nope", value=1)])
    with pytest.raises(ParameterNotDeclaredException):
        node.get_parameter("nope")


def test_declare_with_bad_override_range_raises(make_context):
    node = Node("ranged", context=make_context(["prog", "--ros-args", "-p", "steps:=2"]))
    with pytest.raises(InvalidParameterValueException, match=r"outside the range \[3, 24\].*-p steps:=2"):
        node.declare_parameter("steps", 12, ParameterDescriptor(integer_range=[IntegerRange(
            from_value=3, to_value=24, step=1)]))


def test_parameter_value_api_follows_rclpy(context):
    p = Parameter("k", value=[1.0, 2.0])
    assert (p.name, p.type_, p.value) == ("k", Parameter.Type.DOUBLE_ARRAY, [1.0, 2.0])
    assert Parameter.from_parameter_msg(p.to_parameter_msg()) == p
    assert Parameter("n", Parameter.Type.INTEGER, 3).value == 3
    with pytest.raises(InvalidParameterValueException, match=r"pass the value by keyword: Parameter\('n', value=3\)"):
        Parameter("n", 3)
    with pytest.raises(InvalidParameterValueException, match="must hold values of one type"):
        Parameter("mixed", value=[1, 2.0])
    node = Node("prefixes", context=context, allow_undeclared_parameters=True)
    node.declare_parameters("filter", [("sigma_px", 1.5), ("size_px", 5)])
    assert {k: v.value for k, v in node.get_parameters_by_prefix("filter").items()} == {"sigma_px": 1.5, "size_px": 5}
    assert node.get_parameter("undeclared_ok").type_ == Parameter.Type.NOT_SET
    assert node.get_parameter_or("missing", 7).value == 7


def test_automatically_declare_parameters_from_overrides(make_context):
    node = Node("auto", context=make_context(["prog", "--ros-args", "-p", "x:=1", "-p", "y:=[a, b]"]),
                automatically_declare_parameters_from_overrides=True)
    assert node.get_parameter("x").value == 1 and node.get_parameter("y").value == ["a", "b"]


def test_params_file_errors_name_the_file_and_key(tmp_path):
    missing_key = _write(tmp_path / "bad.yaml", "talker:\n  rate: 1\n")
    with pytest.raises(ROSArgumentsError, match=r"bad.yaml: node entry '/talker/rate' must be a mapping"):
        read_params_file(missing_key)
    mixed = _write(tmp_path / "mixed.yaml", "talker:\n  ros__parameters:\n    xs: [1, 2.5]\n")
    with pytest.raises(ROSArgumentsError, match=r"mixed.yaml: /talker: parameter 'xs': list items must all have "
                                                r"one type"):
        read_params_file(mixed)
    with pytest.raises(ROSArgumentsError, match="cannot read parameters file"):
        read_params_file(tmp_path / "absent.yaml")


def test_node_patterns_follow_ros2_wildcards():
    assert node_pattern_matches("/**", "/a/b/cam")
    assert node_pattern_matches("/*/cam", "/a/cam") and not node_pattern_matches("/*/cam", "/a/b/cam")
    assert node_pattern_matches("/**/cam", "/cam") and node_pattern_matches("/**/cam", "/a/b/cam")
    assert node_pattern_matches("/cam*", "/camera") and not node_pattern_matches("/cam", "/a/cam")
    source = parse_params_yaml({"scanner": {"cloud": {"ros__parameters": {"min": 0.1}}},
                                "/**": {"ros__parameters": {"frame_id": "f"}}})
    assert source.entries == (("/**", {"frame_id": "f"}), ("/scanner/cloud", {"min": 0.1}))
