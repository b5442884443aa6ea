"""sensor_msgs/Image helpers: from_array / to_array views, encodings, step and padding checks."""

from __future__ import annotations

import numpy as np
import pytest

from dptpu.messages import Header, Image, Time, decode, encode
from dptpu.messages.image_encodings import default_encoding, pixel_layout


@pytest.mark.parametrize(("encoding", "dtype", "shape", "bytes_per_pixel"), [
    ("mono8", np.uint8, (48, 64), 1),
    ("mono16", np.uint16, (48, 64), 2),
    ("32FC1", np.float32, (48, 64), 4),
    ("rgb8", np.uint8, (48, 64, 3), 3),
])
def test_to_array_gives_the_typed_view(encoding, dtype, shape, bytes_per_pixel):
    rng = np.random.default_rng(0)
    pixels = (rng.random(shape) * 200).astype(dtype)
    image = Image.from_array(pixels, encoding)
    assert (image.height, image.width, image.encoding) == (48, 64, encoding)
    assert image.step == 64 * bytes_per_pixel
    assert image.data.dtype == np.uint8 and image.data.shape == (48 * 64 * bytes_per_pixel,)
    view = image.to_array()
    assert view.shape == shape and view.dtype == np.dtype(dtype).newbyteorder("<")
    np.testing.assert_array_equal(view, pixels)
    assert np.shares_memory(view, pixels)  # no copy on either side


def test_default_encodings_by_dtype_and_channels():
    assert Image.from_array(np.zeros((4, 5), np.uint8)).encoding == "mono8"
    assert Image.from_array(np.zeros((4, 5), np.uint16)).encoding == "mono16"
    assert Image.from_array(np.zeros((4, 5), np.float32)).encoding == "32FC1"
    assert Image.from_array(np.zeros((4, 5), np.float64)).encoding == "64FC1"
    assert Image.from_array(np.zeros((4, 5, 3), np.uint8)).encoding == "rgb8"
    assert Image.from_array(np.zeros((4, 5, 4), np.uint16)).encoding == "rgba16"
    assert Image.from_array(np.zeros((4, 5, 3), np.float32)).encoding == "32FC3"
    assert default_encoding(np.dtype(np.int16), 1) == "16SC1"
    assert pixel_layout("bgr8") == (np.dtype(np.uint8), 3)
    with pytest.raises(ValueError, match=r"no image encoding for dtype bool with 1 channel\(s\)"):
        Image.from_array(np.zeros((4, 5), bool))


def test_mono16_bytes_are_little_endian_in_row_major_order():
    pixels = np.array([[0x0102, 0x0304], [0x0506, 0x0708]], dtype=np.uint16)
    image = Image.from_array(pixels, "mono16")
    assert image.is_bigendian == 0 and image.step == 4
    assert image.data.tolist() == [0x02, 0x01, 0x04, 0x03, 0x06, 0x05, 0x08, 0x07]


def test_big_endian_image_round_trips_with_its_byte_order():
    pixels = np.array([[1, 2, 3], [4, 5, 65535]], dtype=">u2")
    image = Image.from_array(pixels)
    assert image.is_bigendian == 1
    assert image.data.tolist()[:4] == [0, 1, 0, 2]
    _, decoded = decode(encode("/img", image))
    view = decoded.to_array()
    assert view.dtype == np.dtype(">u2")
    np.testing.assert_array_equal(view, pixels)


def test_to_array_skips_row_padding_without_copying():
    # 3 rows of 4 mono16 pixels (8 bytes) padded to step = 10 bytes.
    rows = np.zeros((3, 10), np.uint8)
    rows[:, :8] = np.arange(24, dtype=np.uint8).reshape(3, 8)
    rows[:, 8:] = 0xEE  # padding
    image = Image(height=3, width=4, encoding="mono16", step=10, data=rows.reshape(-1))
    view = image.to_array()
    expected = np.arange(24, dtype=np.uint8).reshape(3, 8).view("<u2")
    np.testing.assert_array_equal(view, expected)
    assert view[0, 0] == 0x0100 and view[2, 3] == 0x1716
    assert np.shares_memory(view, rows)
    _, decoded = decode(encode("/img", image))
    np.testing.assert_array_equal(decoded.to_array(), expected)


def test_from_array_copies_a_non_contiguous_array():
    base = np.arange(8 * 10, dtype=np.uint8).reshape(8, 10)
    image = Image.from_array(base[:, ::2])
    assert image.step == 5
    np.testing.assert_array_equal(image.to_array(), base[:, ::2])
    assert not np.shares_memory(image.data, base)


def test_decoded_image_view_is_read_only():
    image = Image.from_array(np.ones((4, 6), np.uint8), header=Header(stamp=Time(sec=3), frame_id="cam"))
    _, decoded = decode(encode("/img", image))
    view = decoded.to_array()
    assert not view.flags.writeable
    assert view.sum() == 24 and decoded.header.frame_id == "cam"


@pytest.mark.parametrize(("fields", "match"), [
    (dict(step=7), r"Image.step must be >= width \* channels \* itemsize = 4 \* 1 \* 2 = 8 for 'mono16'; got 7"),
    (dict(step=10), r"Image.data must hold step \* height = 10 \* 3 = 30 bytes; got 24"),
    (dict(encoding="mono9"), r"unknown image encoding 'mono9'; expected one of mono8, mono16"),
    (dict(encoding="rgb8"),
     r"Image.step must be >= width \* channels \* itemsize = 4 \* 3 \* 1 = 12 for 'rgb8'; got 8"),
    (dict(data=np.zeros(24, np.uint16)), r"Image.data must be a 1-D uint8 ndarray; got ndarray of shape \(24,\) "
                                         r"and dtype uint16"),
])
def test_to_array_rejects_bad_step_and_encoding(fields, match):
    values = dict(height=3, width=4, encoding="mono16", step=8, data=np.zeros(24, np.uint8))
    values.update(fields)
    with pytest.raises(ValueError, match=match):
        Image(**values).to_array()


def test_from_array_rejects_mismatched_encoding_and_shape():
    with pytest.raises(ValueError, match=r"encoding 'mono8' needs 1 channel\(s\) of uint8; got array of shape "
                                         r"\(4, 5\) and dtype uint16"):
        Image.from_array(np.zeros((4, 5), np.uint16), "mono8")
    with pytest.raises(ValueError, match=r"encoding 'rgb8' needs 3 channel\(s\) of uint8; got array of shape "
                                         r"\(4, 5, 4\)"):
        Image.from_array(np.zeros((4, 5, 4), np.uint8), "rgb8")
    with pytest.raises(ValueError, match=r"image array must be an ndarray of shape \(H, W\) or \(H, W, C\); got "
                                         r"\(4,\)"):
        Image.from_array(np.zeros(4, np.uint8))


def test_unknown_encoding_travels_but_step_is_checked_for_known_ones():
    packed = Image(height=2, width=4, encoding="yuv422", step=8, data=np.zeros(16, np.uint8))
    _, decoded = decode(encode("/img", packed))
    assert decoded.encoding == "yuv422"
    with pytest.raises(ValueError, match=r"Image.step must be >= 8 bytes for 4 pixels of 'mono16'; got 4"):
        Image(height=2, width=4, encoding="mono16", step=4, data=np.zeros(8, np.uint8)).validate()
