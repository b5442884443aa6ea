"""The ROS 2 command line: launch_ros's order, and parameter values that YAML-decode to themselves."""
from __future__ import annotations

import math

import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from dptpu.tools.launch import InlineParameter, ParameterFile, encode_parameter_value, ros_arguments


def test_ros_arguments_follow_launch_ros_order():
    arguments = ros_arguments(name="phase", namespace="/scanner",
                              parameters=[InlineParameter("min_modulation", 5.0), ParameterFile("/p.yaml"),
                                          InlineParameter("mode", "fast")],
                              remaps=[("/camera/image_raw", "/sim/image")])
    assert arguments == ["--ros-args", "-r", "__node:=phase", "-r", "__ns:=/scanner", "-p", "min_modulation:=5.0",
                         "--params-file", "/p.yaml", "-p", "mode:=fast", "-r", "/camera/image_raw:=/sim/image"]
    assert ros_arguments() == ["--ros-args"]  # launch_ros always adds it


@pytest.mark.parametrize(("value", "text"), [
    (5.0, "5.0"), (1e-05, "1.0e-05"), (3, "3"), (True, "true"), (False, "false"), ("hello", "hello"),
    ("10", "'10'"), ("true", "'true'"), ("", "''"), ("a b", "a b"), ([1, 2, 3], "[1, 2, 3]"),
    (["a", "10"], '["a", "10"]'), ([], "[]"), (float("inf"), ".inf"), ("two\nlines", '"two\\nlines"'),
])
def test_encode_parameter_value_examples(value, text):
    assert encode_parameter_value(value) == text
    assert yaml.safe_load(text) == value


@pytest.mark.parametrize("value", [None, {"a": 1}, [[1]], [None], object()])
def test_encode_parameter_value_rejects_what_a_parameter_cannot_hold(value):
    with pytest.raises(ValueError, match="parameter"):
        encode_parameter_value(value)


_TEXT = st.text(st.characters(exclude_categories=("Cs",)), max_size=20)
_SCALARS = st.one_of(st.booleans(), st.integers(-2 ** 63, 2 ** 63 - 1), st.floats(allow_nan=True), _TEXT)
_ARRAYS = st.one_of(st.lists(st.booleans(), max_size=4), st.lists(st.integers(-1000, 1000), max_size=4),
                    st.lists(st.floats(allow_nan=False), max_size=4), st.lists(_TEXT, max_size=4))


def _same(decoded, value) -> bool:
    if isinstance(value, float) and math.isnan(value):
        return isinstance(decoded, float) and math.isnan(decoded)
    return type(decoded) is type(value) and decoded == value


@settings(max_examples=300, deadline=None)
@given(st.one_of(_SCALARS, _ARRAYS))
def test_encoded_values_decode_to_the_same_value_and_type(value):
    text = encode_parameter_value(value)
    assert "\n" not in text  # one argv word, one line
    decoded = yaml.safe_load(text)
    if isinstance(value, list):
        assert isinstance(decoded, list) and len(decoded) == len(value)
        assert all(_same(d, v) for d, v in zip(decoded, value))
    else:
        assert _same(decoded, value)
