"""The bridge's ROS 2 DDS types: names, member layout, and the fast XCDR1 path against Cyclone's serializer."""
from __future__ import annotations

import numpy as np
import pytest

from dptpu.messages import CameraInfo, Header, Image, PointCloud2, Time
from dptpu.nodes.ros2_bridge.ros2_idl import (
    CameraInfo_,
    Image_,
    PointCloud2_,
    Trigger_Request_,
    _as_library_sample,
    ros_topic_name,
    to_dds,
)
from dptpu.nodes.ros2_bridge.ros2_qos import cyclone_config_xml, ros2_qos


def _library_bytes(sample) -> bytes:
    """Cyclone's own XCDR1 serialization, padded to 4 bytes as its DataWriter pads it."""
    raw = type(sample).__mro__[1].serialize(_as_library_sample(sample), use_version_2=False)
    return raw + b"\x00" * (-len(raw) % 4)


def test_type_names_are_ros2_dds_names():
    assert PointCloud2_.__idl_typename__ == "sensor_msgs::msg::dds_::PointCloud2_"
    assert Image_.__idl_typename__ == "sensor_msgs::msg::dds_::Image_"
    assert CameraInfo_.__idl_typename__ == "sensor_msgs::msg::dds_::CameraInfo_"
    assert Trigger_Request_.__idl_typename__ == "std_srvs::srv::dds_::Trigger_Request_"
    assert list(PointCloud2_.__dataclass_fields__) == ["header", "height", "width", "fields", "is_bigendian",
                                                       "point_step", "row_step", "data", "is_dense"]
    assert ros_topic_name("/scanner/points") == "rt/scanner/points"
    assert ros_topic_name("/scanner/capture", prefix="rq") + "Request" == "rq/scanner/captureRequest"
    with pytest.raises(ValueError, match="must be absolute"):
        ros_topic_name("scanner/points")


@pytest.mark.parametrize("width, height", [(3, 2), (7, 5)])
def test_fast_point_cloud_serialization_equals_cyclones(width, height):
    rng = np.random.default_rng(width)
    points = rng.normal(size=(height, width, 5)).astype(np.float32)  # (H, W, 5)
    points[0, 0, :3] = np.nan
    cloud = PointCloud2.from_array(points, ["x", "y", "z", "intensity", "quality"],
                                   header=Header(stamp=Time(sec=17, nanosec=999_999_999), frame_id="odd_len"))
    sample = to_dds(cloud)
    fast = sample.serialize()
    assert fast[:4] == b"\x00\x01\x00\x00"  # CDR_LE, what rmw_cyclonedds writes
    assert fast == _library_bytes(sample)
    back = PointCloud2_.deserialize(fast)
    assert bytes(back.data) == cloud.data.tobytes() and back.point_step == 20 and back.row_step == 20 * width
    assert [(f.name, f.offset, f.datatype, f.count) for f in back.fields] == \
        [("x", 0, 7, 1), ("y", 4, 7, 1), ("z", 8, 7, 1), ("intensity", 12, 7, 1), ("quality", 16, 7, 1)]


def test_fast_image_serialization_equals_cyclones_and_camera_info_round_trips():
    depth = np.arange(35, dtype=np.float32).reshape(5, 7) / 10  # (H, W) metres
    image = Image.from_array(depth, header=Header(stamp=Time(sec=3, nanosec=4), frame_id="scanner_optical_frame"))
    sample = to_dds(image)
    assert sample.serialize() == _library_bytes(sample)
    back = Image_.deserialize(sample.serialize())
    assert (back.encoding, back.step, back.height, back.width) == ("32FC1", 28, 5, 7)
    np.testing.assert_array_equal(np.frombuffer(bytes(back.data), np.float32).reshape(5, 7), depth)
    info = CameraInfo.from_intrinsics(np.array([[500.0, 0, 3], [0, 501.0, 2], [0, 0, 1]]), [0.1, 0, 0, 0, 0], 7, 5)
    back_info = CameraInfo_.deserialize(to_dds(info).serialize(use_version_2=False))
    assert list(back_info.k) == [500.0, 0, 3, 0, 501.0, 2, 0, 0, 1] and list(back_info.p)[:3] == [500.0, 0, 3]


def test_qos_profiles_and_cyclone_configuration():
    from cyclonedds.qos import Policy

    default = ros2_qos("default")
    assert default[Policy.History] == Policy.History.KeepLast(10)
    assert default[Policy.Durability] == Policy.Durability.Volatile
    assert ros2_qos("sensor_data")[Policy.Reliability] == Policy.Reliability.BestEffort
    assert ros2_qos("latched")[Policy.Durability] == Policy.Durability.TransientLocal
    with pytest.raises(ValueError, match="unknown ROS 2 QoS profile 'fast'"):
        ros2_qos("fast")
    assert cyclone_config_xml() is None
    xml = cyclone_config_xml("lo", ("127.0.0.1",))
    assert '<NetworkInterface name="lo"/>' in xml and "<AllowMulticast>false</AllowMulticast>" in xml
    assert '<Peer Address="127.0.0.1"/>' in xml


def test_fast_deserialization_equals_cyclones():
    cloud = PointCloud2.from_array(np.arange(60, dtype=np.float32).reshape(3, 4, 5), ["x", "y", "z", "a", "b"],
                                   header=Header(stamp=Time(sec=-3, nanosec=5), frame_id="f"))
    raw = to_dds(cloud).serialize()
    fast = PointCloud2_.deserialize(raw)
    slow = type(fast).__mro__[1].deserialize.__func__(PointCloud2_, raw)  # Cyclone's IdlStruct.deserialize
    assert fast.header == slow.header and fast.fields == slow.fields
    assert (fast.height, fast.width, fast.point_step, fast.row_step, fast.is_dense) == \
        (slow.height, slow.width, slow.point_step, slow.row_step, slow.is_dense)
    assert fast.data == bytes(slow.data) == cloud.data.tobytes()
    image = Image.from_array(np.arange(6, dtype=np.uint16).reshape(2, 3))
    back = Image_.deserialize(to_dds(image).serialize())
    assert (back.encoding, back.step, back.data) == ("mono16", 6, image.data.tobytes())
    with pytest.raises(ValueError, match="ends at byte"):
        PointCloud2_.deserialize(raw[:40])
