"""sensor_msgs/PointCloud2 helpers against hand-computed layouts; structured and (H, W, C) views."""

from __future__ import annotations

import numpy as np
import pytest

from dptpu.messages import PointCloud2, PointField, decode, encode


def test_layout_of_a_640x480_xyzi_float32_cloud():
    rng = np.random.default_rng(0)
    points = rng.normal(size=(480, 640, 4)).astype(np.float32)
    cloud = PointCloud2.from_array(points, ("x", "y", "z", "intensity"))
    assert (cloud.height, cloud.width) == (480, 640)
    assert [(f.name, f.offset, f.datatype, f.count) for f in cloud.fields] == [
        ("x", 0, 7, 1), ("y", 4, 7, 1), ("z", 8, 7, 1), ("intensity", 12, 7, 1)]
    assert cloud.point_step == 16
    assert cloud.row_step == 640 * 16 == 10240
    assert cloud.data.shape == (480 * 10240,) == (4_915_200,)
    assert cloud.is_bigendian is False and cloud.is_dense is True
    # Point (row 2, col 3) starts at byte 2 * row_step + 3 * point_step; its z is 8 bytes further.
    start = 2 * 10240 + 3 * 16
    assert cloud.data[start + 8:start + 12].view("<f4")[0] == points[2, 3, 2]
    back = cloud.to_array()
    assert back.shape == (480, 640, 4) and np.shares_memory(back, points)
    np.testing.assert_array_equal(back, points)


def test_datatype_constants_match_ros():
    constants = [PointField.INT8, PointField.UINT8, PointField.INT16, PointField.UINT16, PointField.INT32,
                 PointField.UINT32, PointField.FLOAT32, PointField.FLOAT64]
    assert constants == [1, 2, 3, 4, 5, 6, 7, 8]


def test_structured_round_trip_with_padding_subarrays_and_mixed_types():
    dtype = np.dtype({"names": ["x", "y", "z", "rgb", "ring", "t"],
                      "formats": ["<f4", "<f4", "<f4", ("u1", (3,)), "<u2", "<f8"],
                      "offsets": [0, 4, 8, 12, 16, 24], "itemsize": 32})
    rng = np.random.default_rng(0)
    points = np.zeros((3, 4), dtype)
    points["x"] = rng.normal(size=(3, 4))
    points["rgb"] = rng.integers(0, 256, (3, 4, 3))
    points["ring"] = [[0], [1], [2]]
    points["t"] = rng.random((3, 4))
    cloud = PointCloud2.from_structured(points)
    assert [(f.name, f.offset, f.datatype, f.count) for f in cloud.fields] == [
        ("x", 0, PointField.FLOAT32, 1), ("y", 4, PointField.FLOAT32, 1), ("z", 8, PointField.FLOAT32, 1),
        ("rgb", 12, PointField.UINT8, 3), ("ring", 16, PointField.UINT16, 1), ("t", 24, PointField.FLOAT64, 1)]
    assert (cloud.point_step, cloud.row_step, cloud.data.size) == (32, 128, 384)
    _, decoded = decode(encode("/points", cloud))
    structured = decoded.to_structured()
    assert structured.shape == (3, 4) and structured.dtype == dtype
    assert not structured.flags.writeable
    for name in dtype.names:
        np.testing.assert_array_equal(structured[name], points[name])
    xyt = decoded.to_array(("x", "ring", "t"))  # mixed types: a float64 copy
    assert xyt.dtype == np.float64 and xyt.shape == (3, 4, 3)
    np.testing.assert_array_equal(xyt[:, :, 1], [[0] * 4, [1] * 4, [2] * 4])
    with pytest.raises(ValueError, match=r"field 'rgb' has count 3; to_array reads count-1 fields only"):
        decoded.to_array(("rgb",))


def test_unorganized_cloud_from_n_by_c_array():
    xyz = np.arange(30, dtype=np.float64).reshape(10, 3)
    cloud = PointCloud2.from_array(xyz, ["x", "y", "z"])
    assert (cloud.height, cloud.width, cloud.point_step, cloud.row_step) == (1, 10, 24, 240)
    assert {f.datatype for f in cloud.fields} == {PointField.FLOAT64}
    np.testing.assert_array_equal(cloud.to_array()[0], xyz)
    flat = np.zeros(5, dtype=[("x", "<f4"), ("i", "<u2")])
    assert PointCloud2.from_structured(flat).height == 1


def test_organized_cloud_keeps_nan_and_is_not_dense():
    xyz = np.ones((6, 8, 3), np.float32)
    xyz[2, 3] = np.nan
    cloud = PointCloud2.from_array(xyz, ("x", "y", "z"))
    assert cloud.is_dense is False
    _, decoded = decode(encode("/points", cloud))
    back = decoded.to_array()
    assert np.isnan(back[2, 3]).all() and np.isfinite(back).sum() == 6 * 8 * 3 - 3
    assert decoded.is_dense is False
    structured = np.zeros((2, 2), dtype=[("x", "<f4"), ("q", "<u1")])
    assert PointCloud2.from_structured(structured).is_dense is True
    structured["x"][0, 1] = np.nan
    assert PointCloud2.from_structured(structured).is_dense is False


def test_to_array_selects_and_reorders_fields():
    points = np.arange(2 * 3 * 4, dtype=np.float32).reshape(2, 3, 4)
    cloud = PointCloud2.from_array(points, ("x", "y", "z", "quality"))
    zx = cloud.to_array(("z", "x"))
    np.testing.assert_array_equal(zx, points[:, :, [2, 0]])
    assert not np.shares_memory(zx, points)
    xyz = cloud.to_array(("x", "y", "z"), dtype=np.float64)
    np.testing.assert_array_equal(xyz, points[:, :, :3])
    with pytest.raises(ValueError, match=r"PointCloud2 has no field\(s\) 'w'; it has 'x', 'y', 'z', 'quality'"):
        cloud.to_array(("x", "w"))


def test_row_padding_is_skipped():
    # 2 rows of 2 points (x float32), row_step 12 bytes: 4 bytes of padding per row.
    data = np.zeros((2, 12), np.uint8)
    data[:, :8] = np.array([[1.0, 2.0], [3.0, 4.0]], "<f4").view(np.uint8)
    cloud = PointCloud2(height=2, width=2, fields=[PointField(name="x", offset=0, datatype=7, count=1)],
                        point_step=4, row_step=12, data=data.reshape(-1))
    np.testing.assert_array_equal(cloud.to_array()[:, :, 0], [[1.0, 2.0], [3.0, 4.0]])
    np.testing.assert_array_equal(cloud.to_structured()["x"], [[1.0, 2.0], [3.0, 4.0]])


@pytest.mark.parametrize(("changes", "match"), [
    (dict(point_step=16, row_step=32), r"PointCloud2.data must hold row_step \* height = 32 \* 2 = 64 bytes; got 48"),
    (dict(row_step=20), r"PointCloud2.row_step must be >= width \* point_step = 2 \* 12 = 24; got 20"),
    (dict(fields=[PointField(name="x", offset=10, datatype=7)]), r"PointField 'x' spans bytes \[10, 14\) of a point "
                                                                 r"but point_step is 12"),
    (dict(fields=[PointField(name="x", offset=0, datatype=9)]), r"PointField 'x' has datatype 9; expected 1"),
    (dict(fields=[PointField(name="x", datatype=7), PointField(name="x", offset=4, datatype=7)]),
     r"PointField name 'x' appears twice"),
])
def test_inconsistent_layouts_are_refused(changes, match):
    cloud = PointCloud2.from_array(np.zeros((2, 2, 3), np.float32), ("x", "y", "z"))
    for name, value in changes.items():
        setattr(cloud, name, value)
    with pytest.raises(ValueError, match=match):
        cloud.to_structured()
    with pytest.raises(ValueError, match=match):
        encode("/points", cloud)


def test_from_array_rejects_bad_input():
    with pytest.raises(ValueError, match=r"array must be float32 or float64; got int32"):
        PointCloud2.from_array(np.zeros((2, 2, 3), np.int32), "xyz")
    with pytest.raises(ValueError, match=r"field_names must be a sequence of names such as \('x', 'y', 'z'\); got "
                                         r"the string 'xyz'"):
        PointCloud2.from_array(np.zeros((2, 2, 3), np.float32), "xyz")
    with pytest.raises(ValueError, match=r"field_names must name all 3 channels of an array of shape \(2, 2, 3\); "
                                         r"got 2 names"):
        PointCloud2.from_array(np.zeros((2, 2, 3), np.float32), ("x", "y"))
    with pytest.raises(ValueError, match=r"points must have a structured dtype with named fields; got float32"):
        PointCloud2.from_structured(np.zeros((2, 2), np.float32))
