"""Message schema: registry names, equality, repr and ROS 2 .msg definitions."""

from __future__ import annotations

import numpy as np
import pytest

from dptpu.messages import CameraInfo, Image, PhaseMaps, PointField, lookup, message_definition, registered_types
from dptpu.messages.registry import register
from dptpu.messages.schema import Message, message, scalar

ROS_IMAGE_FIELDS = """std_msgs/Header header
uint32 height
uint32 width
string encoding
uint8 is_bigendian
uint32 step
uint8[] data"""


def test_registry_uses_ros2_names():
    types = registered_types()
    assert types["sensor_msgs/msg/Image"] is Image
    assert lookup("sensor_msgs/msg/CameraInfo") is CameraInfo
    assert lookup("dptpu_msgs/msg/PhaseMaps") is PhaseMaps
    own = [name for name, cls in types.items() if cls.__module__.startswith("dptpu.messages")]
    assert all(name.startswith(("builtin_interfaces/", "std_msgs/", "sensor_msgs/", "diagnostic_msgs/",
                                "geometry_msgs/", "tf2_msgs/", "dptpu_msgs/")) for name in own)
    with pytest.raises(KeyError, match=r"unknown message type 'sensor_msgs/msg/Imu'"):
        lookup("sensor_msgs/msg/Imu")


def test_registry_refuses_bad_or_taken_names():
    with pytest.raises(ValueError, match=r"message type name must look like 'package/msg/Type'; got 'Image'"):
        register("Image", Image)
    with pytest.raises(ValueError, match=r"'sensor_msgs/msg/Image' is already registered to "
                                         r"dptpu.messages.sensor.Image"):
        @message("sensor_msgs/msg/Image")
        class Impostor(Message):
            height: int = scalar("uint32")


def test_message_definition_matches_ros2():
    text = message_definition(Image)
    assert text.startswith(ROS_IMAGE_FIELDS + "\n" + "=" * 80 + "\nMSG: std_msgs/Header\n")
    assert "MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec" in text
    camera_info = message_definition(CameraInfo).split("\n")
    assert camera_info[3:8] == ["string distortion_model", "float64[] d", "float64[9] k", "float64[9] r",
                                "float64[12] p"]
    assert "float32[] phases  # shape (F, H, W), row-major" in message_definition(PhaseMaps)
    assert message_definition(PointField) == "string name\nuint32 offset\nuint8 datatype\nuint32 count"


def test_equality_is_bit_exact_and_repr_summarizes_arrays():
    a = Image.from_array(np.zeros((40, 50), np.uint8))
    b = Image.from_array(np.zeros((40, 50), np.uint8))
    assert a == b
    b.data[0] = 1
    assert a != b
    assert "data=<ndarray (2000,) uint8>" in repr(a)
    nan_maps = PhaseMaps(frequencies=np.array([np.nan]), phases=np.full((1, 2, 2), np.nan, np.float32))
    assert nan_maps == PhaseMaps(frequencies=np.array([np.nan]), phases=np.full((1, 2, 2), np.nan, np.float32))
    with pytest.raises(TypeError, match="unhashable"):
        hash(a)


def test_every_field_must_be_declared():
    with pytest.raises(TypeError, match=r"Loose.count must be declared with scalar\(\)"):
        @message("dptpu_msgs/msg/Loose")
        class Loose(Message):
            count: int = 0
