"""Echo output: arrays summarized, ros2-shaped YAML, strict JSON, ros2 service call repr."""

from __future__ import annotations

import json

import numpy as np
import pytest
import yaml

from dptpu.graph import SetBool, Trigger
from dptpu.messages import CameraInfo, Header, Image, PhaseMaps, PointCloud2, Time
from dptpu.tools.introspection import message_repr, message_to_dict, message_to_json, message_to_yaml, summarize_array


def test_summary_of_a_uint8_image_stack_gives_dtype_shape_min_max_mean():
    rng = np.random.default_rng(0)
    stack = rng.integers(3, 250, size=(24, 48, 64), dtype=np.uint8)
    summary = summarize_array(stack)
    assert summary == {"dtype": "uint8", "shape": [24, 48, 64], "min": int(stack.min()), "max": int(stack.max()),
                       "mean": pytest.approx(float(stack.mean()))}
    assert isinstance(summary["min"], int) and isinstance(summary["mean"], float)


def test_float_summary_ignores_and_counts_nonfinite_values():
    values = np.array([[1.0, np.nan], [-np.inf, 3.0]], dtype=np.float32)
    assert summarize_array(values) == {"dtype": "float32", "shape": [2, 2], "min": 1.0, "max": 3.0, "mean": 2.0,
                                       "nonfinite": 2}
    assert summarize_array(np.full(3, np.nan))["min"] is None


def test_bool_and_empty_summaries():
    assert summarize_array(np.array([True, False, False, False])) == {
        "dtype": "bool", "shape": [4], "min": False, "max": True, "mean": 0.25}
    assert summarize_array(np.zeros((0, 5), np.int32)) == {"dtype": "int32", "shape": [0, 5], "min": None,
                                                          "max": None, "mean": None}
    with pytest.raises(ValueError, match="values must be a bool, integer or float ndarray; got list"):
        summarize_array([1, 2])


def _image() -> Image:
    pixels = (7 + np.arange(32)).astype(np.uint8).reshape(4, 8)
    return Image.from_array(pixels, header=Header(stamp=Time(sec=5, nanosec=6), frame_id="cam"))


def test_message_to_dict_keeps_structure_and_summarizes_only_arrays():
    data = message_to_dict(_image())
    assert data == {"header": {"stamp": {"sec": 5, "nanosec": 6}, "frame_id": "cam"}, "height": 4, "width": 8,
                    "encoding": "mono8", "is_bigendian": 0, "step": 8,
                    "data": {"dtype": "uint8", "shape": [32], "min": 7, "max": 38, "mean": 22.5}}


def test_short_sequences_are_printed_long_ones_summarized():
    camera_matrix = np.array([[500.0, 0, 320], [0, 500, 240], [0, 0, 1]])
    info = CameraInfo.from_intrinsics(camera_matrix, np.zeros(5), 640, 480)
    data = message_to_dict(info)  # default: up to 16 values printed
    assert data["k"] == [500.0, 0.0, 320.0, 0.0, 500.0, 240.0, 0.0, 0.0, 1.0]
    assert len(data["p"]) == 12 and data["d"] == [0.0] * 5
    short = message_to_dict(info, max_sequence_length=9)
    assert short["k"] == data["k"]
    assert short["p"] == {"dtype": "float64", "shape": [12], "min": 0.0, "max": 500.0,
                          "mean": pytest.approx((500 + 320 + 500 + 240 + 1) / 12), "nonfinite": 0}
    with pytest.raises(ValueError, match="max_sequence_length must be an int >= 0; got -1"):
        message_to_dict(info, max_sequence_length=-1)


def test_yaml_has_the_ros2_echo_layout_and_loads_back():
    data = message_to_dict(_image())
    text = message_to_yaml(data)
    assert text.splitlines() == [
        "header:", "  stamp:", "    sec: 5", "    nanosec: 6", "  frame_id: cam", "height: 4", "width: 8",
        "encoding: mono8", "is_bigendian: 0", "step: 8",
        "data: {dtype: uint8, shape: [32], min: 7, max: 38, mean: 22.5}"]
    assert yaml.safe_load(text) == data


def test_yaml_of_message_lists_and_quoted_strings_loads_back():
    points = np.zeros((2, 3), dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4")])
    cloud = PointCloud2.from_structured(points, header=Header(frame_id="a: b"))
    data = message_to_dict(cloud)
    text = message_to_yaml(data)
    assert "fields:\n- name: x\n  offset: 0\n" in text
    assert "  frame_id: 'a: b'" in text.splitlines()
    assert yaml.safe_load(text) == data


def test_json_is_strict_and_one_line():
    maps = PhaseMaps(frequencies=np.array([1.0]), phases=np.full((1, 2, 2), np.nan, np.float32),
                     modulation=np.ones((1, 2, 2), np.float32), valid=np.zeros((2, 2), bool))
    text = message_to_json(message_to_dict(maps))
    assert "\n" not in text and "NaN" not in text
    data = json.loads(text)
    assert data["phases"] == {"dtype": "float32", "shape": [1, 2, 2], "min": None, "max": None, "mean": None,
                              "nonfinite": 4}
    assert data["valid"]["mean"] == 0.0 and data["frequencies"] == [1.0]


def test_repr_is_the_ros2_service_call_form():
    assert message_repr(Trigger.Request()) == "std_srvs.srv.Trigger_Request()"
    assert message_repr(SetBool.Response(success=True, message="it's on")) == \
        "std_srvs.srv.SetBool_Response(success=True, message=\"it's on\")"
    assert message_repr(_image()) == (
        "sensor_msgs.msg.Image(header=std_msgs.msg.Header(stamp=builtin_interfaces.msg.Time(sec=5, nanosec=6), "
        "frame_id='cam'), height=4, width=8, encoding='mono8', is_bigendian=0, step=8, "
        "data=<uint8 array shape (32,) min=7 max=38 mean=22.5>)")
