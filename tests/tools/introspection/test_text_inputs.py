"""YAML inputs of the CLI: service requests (``service call``) and parameter values (``param set/get/dump``)."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from dptpu.graph import Parameter, SetBool, Trigger
from dptpu.graph.rcl_interfaces import GetParameters, ListParameters
from dptpu.messages import CameraInfo, Image
from dptpu.tools.introspection import format_parameter_value, message_from_yaml, parameters_yaml, parse_parameter_value


def test_request_from_yaml_fills_scalars_nested_lists_and_defaults():
    assert message_from_yaml(SetBool.Request, "{data: true}") == SetBool.Request(data=True)
    assert message_from_yaml(Trigger.Request, "") == Trigger.Request()
    assert message_from_yaml(ListParameters.Request, "depth: 2") == ListParameters.Request(depth=2)
    request = message_from_yaml(GetParameters.Request, "{names: [{data: level}, {data: rate_hz}]}")
    assert [item.data for item in request.names] == ["level", "rate_hz"]


def test_request_from_yaml_fills_sequences_and_arrays_with_their_dtypes():
    info = message_from_yaml(CameraInfo, "{header: {frame_id: cam, stamp: {sec: 3}}, k: [1, 0, 2, 0, 1, 3, 0, 0, 1]}")
    assert info.header.frame_id == "cam" and info.header.stamp.sec == 3
    assert info.k.dtype == np.float64 and info.k.tolist() == [1.0, 0.0, 2.0, 0.0, 1.0, 3.0, 0.0, 0.0, 1.0]
    image = message_from_yaml(Image, "{height: 1, width: 3, encoding: mono8, step: 3, data: [1, 2, 255]}")
    assert image.data.dtype == np.uint8 and image.to_array().tolist() == [[1, 2, 255]]


@pytest.mark.parametrize("message_type, text, message", [
    (SetBool.Request, "{data: 1}", "SetBool.Request.data must be bool; got int 1"),
    (SetBool.Request, "{dat: true}", "SetBool.Request has no field\\(s\\) dat; its fields: data"),
    (SetBool.Request, "[true]", "SetBool.Request must be a mapping of field values"),
    (SetBool.Request, "{data: [", "request values are not valid YAML"),
    (ListParameters.Request, "{depth: -1}",
     "ListParameters.Request.depth must be uint64 in \\[0, 18446744073709551615\\]; got -1"),
    (CameraInfo, "{k: [1, 2]}", "CameraInfo.k must have shape \\(9,\\); got \\(2,\\)"),
    (Image, "{height: 1, width: 2, encoding: mono8, step: 2, data: [1, 300]}",
     "Image.data values must lie in \\[0, 255\\] for uint8; got \\[1, 300\\]"),
    (Image, "{height: 2, width: 2, encoding: mono8, step: 2, data: [1, 2]}", "Image.data must hold step \\* height"),
])
def test_bad_requests_name_the_field_and_what_was_expected(message_type, text, message):
    with pytest.raises(ValueError, match=message):
        message_from_yaml(message_type, text)


@pytest.mark.parametrize("text, value", [
    ("5", 5), ("5.0", 5.0), ("-1e-3", -0.001), ("2E+2", 200.0), ("'1e-3'", "1e-3"), ("true", True),
    ("hello", "hello"), ("'5'", "5"),
    ("[1, 2]", [1, 2]), ("[0.5, 1.5]", [0.5, 1.5]), ("[a, b]", ["a", "b"]), ("[]", []),
])
def test_parameter_values_are_yaml_typed_as_ros2_param_set(text, value):
    parsed = parse_parameter_value(text)
    assert parsed == value and type(parsed) is type(value)


@pytest.mark.parametrize("text, message", [
    ("{a: 1}", "must be a scalar or a list, not a mapping"),
    ("", "must not be empty or null"),
    ("[1, x]", "a list parameter must hold values of one type"),
    ("[a", "is not valid YAML"),
])
def test_bad_parameter_values(text, message):
    with pytest.raises(ValueError, match=message):
        parse_parameter_value(text)


def test_get_lines_are_the_ros2_param_get_lines():
    T = Parameter.Type
    assert format_parameter_value(T.INTEGER, 5) == "Integer value is: 5"
    assert format_parameter_value(T.DOUBLE, 20.0) == "Double value is: 20.0"
    assert format_parameter_value(T.BOOL, False) == "Boolean value is: False"
    assert format_parameter_value(T.STRING, "cam") == "String value is: cam"
    assert format_parameter_value(T.STRING_ARRAY, ["a", "b"]) == "String values are: ['a', 'b']"
    assert format_parameter_value(T.BYTE_ARRAY, b"\x01\x02") == "Byte values are: [1, 2]"
    assert format_parameter_value(T.NOT_SET, None) == "Parameter not set."
    assert format_parameter_value(T.DOUBLE, 2.5, hide_type=True) == "2.5"


def test_dump_is_ros2_parameter_yaml_with_dotted_names_nested():
    text = parameters_yaml("/scanner/phase", {"steps": 12, "nested.x": 1, "nested.y.z": [0.5], "use_sim_time": False,
                                              "unset": None})
    assert text == ("/scanner/phase:\n  ros__parameters:\n    nested:\n      x: 1\n      y:\n        z:\n"
                    "        - 0.5\n    steps: 12\n    use_sim_time: false\n")
    assert yaml.safe_load(text) == {"/scanner/phase": {"ros__parameters": {
        "nested": {"x": 1, "y": {"z": [0.5]}}, "steps": 12, "use_sim_time": False}}}
    with pytest.raises(ValueError, match="node_name must be a fully qualified name starting with '/'; got 'phase'"):
        parameters_yaml("phase", {})
