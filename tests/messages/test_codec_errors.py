"""Strict decoding: every malformed, oversized or unexpected message raises DecodeError naming the problem;
bad messages to encode raise EncodeError naming the field."""

from __future__ import annotations

import re

import msgpack
import numpy as np
import pytest

from dptpu.messages import (
    AbsolutePhase,
    CameraInfo,
    DecodeError,
    DecodeLimits,
    EncodeError,
    FringeFrame,
    Header,
    Image,
    PatternEntry,
    PhaseMaps,
    PointCloud2,
    Trigger,
    decode,
    encode,
)

TOPIC = "/camera/image_raw"


def _image_frames() -> list:
    pixels = np.random.default_rng(0).integers(0, 256, (6, 8), dtype=np.uint8)
    return [bytes(frame) for frame in encode(TOPIC, Image.from_array(pixels))]


def _header_of(frames) -> dict:
    return msgpack.unpackb(frames[1], ext_hook=msgpack.ExtType)


def _with_header(frames, header: dict) -> list:
    return [frames[0], msgpack.packb(header, use_bin_type=True), *frames[2:]]


def _crafted(dtype: str, shape, frame: bytes, type_name="sensor_msgs/msg/Image") -> list:
    """An Image-typed message whose single array has the given descriptor and frame."""
    header = _header_of(_image_frames())
    header["type"] = type_name
    header["arrays"] = [[dtype, shape]]
    return _with_header([TOPIC.encode(), b"", frame], header)


def test_decode_error_is_a_value_error():
    assert issubclass(DecodeError, ValueError)


def test_too_many_frames():
    frames = _image_frames()
    with pytest.raises(DecodeError, match=r"too many frames: 67 > max_frames 66"):
        decode(frames + [b""] * 64)
    with pytest.raises(DecodeError, match=r"too many frames: 3 > max_frames 2"):
        decode(frames, limits=DecodeLimits(max_frames=2))


def test_too_few_frames_and_non_list_frames():
    with pytest.raises(DecodeError, match=r"at least 2 frames \(topic, header\); got 1"):
        decode([b"/topic"])
    with pytest.raises(DecodeError, match="frames must be a list of frames; got bytes"):
        decode(b"/topic")
    with pytest.raises(DecodeError, match=r"frame 1 is a int; expected bytes, memoryview or a zmq.Frame"):
        decode([b"/topic", 12])


@pytest.mark.parametrize(("shape", "match"), [
    ([2**40, 2**40], r"more than max_dims_product 536870912 elements"),
    ([2**64 - 1], r"more than max_dims_product"),
    ([1] * 9, r"9 dimensions > max_ndim 8"),
    ([2**29], r"536870912 bytes > max_array_bytes"),
])
def test_oversized_declared_shape(shape, match):
    limits = DecodeLimits(max_array_bytes=2**29 - 1)
    with pytest.raises(DecodeError, match=match):
        decode(_crafted("|u1", shape, b"\x00" * 16), limits=limits)


@pytest.mark.parametrize("dtype", ["|O", "O", ">f8", ">u2", "<U4", "|V8", "<c16", "<M8[ns]", "f8", "uint8", ""])
def test_dtype_outside_the_allow_list(dtype):
    with pytest.raises(DecodeError, match=re.escape(f"array 0: dtype '{dtype}' is not allowed; allowed dtypes: |b1")):
        decode(_crafted(dtype, [2], b"\x00" * 16))


def test_dtype_allowed_but_not_the_fields_dtype():
    with pytest.raises(DecodeError, match=r"Image.data must have dtype uint8 \(\|u1\); got <f8"):
        decode(_crafted("<f8", [6], b"\x00" * 48))


def test_shape_bytes_mismatch():
    with pytest.raises(DecodeError, match=r"array 0: shape \[10\] of <f4 needs 40 bytes; its frame has 39"):
        decode(_crafted("<f4", [10], b"\x00" * 39))
    with pytest.raises(DecodeError, match=r"needs 40 bytes; its frame has 41"):
        decode(_crafted("<f4", [10], b"\x00" * 41))


def test_truncated_array_frame():
    frames = _image_frames()
    frames[2] = frames[2][:-1]
    with pytest.raises(DecodeError, match=r"array 0: shape \[48\] of \|u1 needs 48 bytes; its frame has 47"):
        decode(frames)


def test_truncated_header_frame():
    frames = _image_frames()
    frames[1] = frames[1][: len(frames[1]) // 2]
    with pytest.raises(DecodeError, match=r"header is not valid msgpack"):
        decode(frames)


@pytest.mark.parametrize(("header", "match"), [
    (b"\xc1garbage", r"header is not valid msgpack"),
    (b"\x00\x01\x02", r"header is not valid msgpack \(ExtraData"),
    (msgpack.packb([1, 2, 3]), r"header must be a msgpack map; got list"),
    (msgpack.packb({"wire": 1}), r"header must have exactly the keys wire, type, version, fields, arrays; "
                                 r"missing \['type', 'version', 'fields', 'arrays'\]"),
    (msgpack.packb({1: 2}), r"header is not valid msgpack \(ValueError"),
    (b"\xd4\x05\x00", r"header holds msgpack extension type 5; only 1 \(array reference\) is allowed"),
])
def test_garbage_header_bytes(header, match):
    frames = _image_frames()
    with pytest.raises(DecodeError, match=match):
        decode([frames[0], header, *frames[2:]])


def test_unknown_type_and_unexpected_type():
    frames = _image_frames()
    header = _header_of(frames)
    header["type"] = "foo_msgs/msg/Bar"
    with pytest.raises(DecodeError, match=r"unknown message type 'foo_msgs/msg/Bar'"):
        decode(_with_header(frames, header))
    with pytest.raises(DecodeError, match=r"expected a sensor_msgs/msg/PointCloud2; got a sensor_msgs/msg/Image"):
        decode(frames, expected_type=PointCloud2)
    with pytest.raises(ValueError, match=r"expected_type: unknown message type 'nope/msg/Nope'; known types: "
                                         r"builtin_interfaces"):
        decode(frames, expected_type="nope/msg/Nope")


def test_schema_and_wire_version_mismatch():
    frames = _image_frames()
    header = _header_of(frames)
    header["version"] = 2
    with pytest.raises(DecodeError, match=r"schema version mismatch for sensor_msgs/msg/Image: the message has "
                                          r"version 2, this build has 1"):
        decode(_with_header(frames, header))
    header = _header_of(frames)
    header["wire"] = 2
    with pytest.raises(DecodeError, match=r"wire format version 2 is not supported; expected 1"):
        decode(_with_header(frames, header))


def test_wrong_field_names():
    frames = _image_frames()
    header = _header_of(frames)
    header["fields"]["heigth"] = header["fields"].pop("height")
    with pytest.raises(DecodeError, match=r"Image: fields do not match sensor_msgs/msg/Image version 1: missing "
                                          r"\['height'\], unknown \[\"'heigth'\"\]"):
        decode(_with_header(frames, header))
    header = _header_of(frames)
    header["fields"]["header"]["stamp"]["extra"] = 1
    with pytest.raises(DecodeError, match=r"Image.header.stamp: fields do not match builtin_interfaces/msg/Time"):
        decode(_with_header(frames, header))


@pytest.mark.parametrize(("path", "value", "match"), [
    (("height",), "6", r"Image.height must be uint32; got str '6'"),
    (("height",), -1, r"Image.height must be uint32; got int -1"),
    (("height",), 2**32, r"Image.height must be uint32; got int 4294967296"),
    (("height",), True, r"Image.height must be uint32; got bool True"),
    (("height",), 6.0, r"Image.height must be uint32; got float 6.0"),
    (("encoding",), b"mono8", r"Image.encoding must be string; got bytes"),
    (("header", "stamp"), [1, 2], r"Image.header.stamp must be a map of fields; got list"),
    (("header", "frame_id"), None, r"Image.header.frame_id must be string; got NoneType"),
    (("data",), 3, r"Image.data must be an array reference; got int 3"),
])
def test_wrong_field_types(path, value, match):
    frames = _image_frames()
    header = _header_of(frames)
    target = header["fields"]
    for key in path[:-1]:
        target = target[key]
    target[path[-1]] = value
    with pytest.raises(DecodeError, match=match):
        decode(_with_header(frames, header))


def test_array_references_must_be_valid_unique_and_complete():
    frames = _image_frames()
    header = _header_of(frames)
    header["fields"]["data"] = msgpack.ExtType(1, (5).to_bytes(4, "big"))
    with pytest.raises(DecodeError, match=r"Image.data refers to array 5; the message has 1 array"):
        decode(_with_header(frames, header))
    header["fields"]["data"] = msgpack.ExtType(1, b"\x00")
    with pytest.raises(DecodeError, match=r"array reference must hold a 4-byte index; got 1 bytes"):
        decode(_with_header(frames, header))
    header = _header_of(frames)
    header["arrays"].append(["|u1", [3]])
    with pytest.raises(DecodeError, match=r"array frame\(s\) \[1\] are not referenced by any field"):
        decode([*_with_header(frames, header), b"abc"])
    with pytest.raises(DecodeError, match=r"header declares 2 array\(s\) but 1 array frame\(s\) came"):
        decode(_with_header(frames, header))


def test_inconsistent_fields_are_refused():
    frames = _image_frames()
    header = _header_of(frames)
    header["fields"]["step"] = 9  # 9 * 6 != 48 bytes of data
    with pytest.raises(DecodeError, match=r"Image: Image.data must hold step \* height = 9 \* 6 = 54 bytes; got 48"):
        decode(_with_header(frames, header))


def test_topic_and_size_limits():
    frames = _image_frames()
    with pytest.raises(DecodeError, match="topic frame is not valid UTF-8"):
        decode([b"\xff\xfe", *frames[1:]])
    with pytest.raises(DecodeError, match="topic frame is empty"):
        decode([b"", *frames[1:]])
    with pytest.raises(DecodeError, match=r"topic frame has 17 bytes > max_topic_bytes 4"):
        decode(frames, limits=DecodeLimits(max_topic_bytes=4))
    with pytest.raises(DecodeError, match=r"header frame has \d+ bytes > max_header_bytes 16"):
        decode(frames, limits=DecodeLimits(max_header_bytes=16))
    with pytest.raises(DecodeError, match=r"frames hold more than max_total_bytes 100 bytes"):
        decode(frames, limits=DecodeLimits(max_total_bytes=100))


def test_errors_name_topic_and_type():
    frames = _image_frames()
    frames[2] = frames[2][:10]
    with pytest.raises(DecodeError, match=r"^cannot decode message on topic '/camera/image_raw' of type "
                                          r"sensor_msgs/msg/Image: array 0"):
        decode(frames)


def test_decode_limits_must_be_positive_ints():
    with pytest.raises(ValueError, match=r"DecodeLimits.max_ndim must be a positive int; got 0"):
        DecodeLimits(max_ndim=0)
    with pytest.raises(ValueError, match=r"limits must be a DecodeLimits; got dict"):
        decode(_image_frames(), limits={"max_frames": 3})


# --------------------------------------------------------------------------------------------------
# Encoding errors
# --------------------------------------------------------------------------------------------------

def _absolute_phase(**overrides) -> AbsolutePhase:
    fields = dict(absolute_phase=np.zeros((4, 5), np.float32), fringe_order=np.zeros((4, 5), np.int32),
                  valid=np.ones((4, 5), bool), reliability=np.ones((4, 5), np.float32))
    fields.update(overrides)
    return AbsolutePhase(**fields)


def test_encode_rejects_wrong_dtype_ndim_and_non_arrays():
    with pytest.raises(EncodeError, match=r"AbsolutePhase.absolute_phase must have dtype float32 \(<f4\); got "
                                          r"float64 \(convert with .astype\(np.float32\)\)"):
        encode("/t", _absolute_phase(absolute_phase=np.zeros((4, 5))))
    with pytest.raises(EncodeError, match=r"AbsolutePhase.valid must have 2 dimension\(s\) \(H, W\); got shape "
                                          r"\(20,\)"):
        encode("/t", _absolute_phase(valid=np.ones(20, bool)))
    with pytest.raises(EncodeError, match=r"AbsolutePhase.fringe_order must be a numpy ndarray \(H, W\) of int32; "
                                          r"got list"):
        encode("/t", _absolute_phase(fringe_order=[[0] * 5] * 4))
    with pytest.raises(EncodeError, match=r"AbsolutePhase.absolute_phase must have dtype float32 \(<f4\); got "
                                          r"object"):
        encode("/t", _absolute_phase(absolute_phase=np.empty((4, 5), dtype=object)))


def test_encode_rejects_inconsistent_shapes():
    with pytest.raises(EncodeError, match=r"AbsolutePhase.valid must have the shape of absolute_phase \(4, 5\); "
                                          r"got \(5, 4\)"):
        encode("/t", _absolute_phase(valid=np.ones((5, 4), bool)))
    with pytest.raises(EncodeError, match=r"PhaseMaps.frequencies must have one entry per phase map \(F = 2\); got 1"):
        encode("/t", PhaseMaps(frequencies=np.array([8.0]), phases=np.zeros((2, 3, 4), np.float32),
                               modulation=np.zeros((2, 3, 4), np.float32), valid=np.ones((3, 4), bool)))


def test_encode_rejects_out_of_range_and_mistyped_scalars():
    with pytest.raises(EncodeError, match=r"Trigger.step must be uint32 in \[0, 4294967295\]; got -1"):
        encode("/t", Trigger(step=-1))
    with pytest.raises(EncodeError, match=r"Trigger.frequency must be float64; got str '96'"):
        encode("/t", Trigger(frequency="96"))
    with pytest.raises(EncodeError, match=r"Trigger.header must be a Header; got dict"):
        encode("/t", Trigger(header={}))
    with pytest.raises(EncodeError, match=r"Trigger.sequence_id must be uint32; got bool True"):
        encode("/t", Trigger(sequence_id=True))
    with pytest.raises(EncodeError, match=r"CameraInfo.k must have shape \(9,\); got \(3, 3\)"):
        encode("/t", CameraInfo(k=np.eye(3)))
    with pytest.raises(EncodeError, match=r"CameraInfo.d must hold float64 values; got dtype <U1"):
        encode("/t", CameraInfo(d=["a"]))


def test_encode_rejects_non_messages_and_bad_topics():
    with pytest.raises(EncodeError, match=r"msg must be a registered message .*; got dict"):
        encode("/t", {"height": 1})
    with pytest.raises(EncodeError, match=r"topic must be a non-empty str or bytes; got ''"):
        encode("", Header())


def test_validate_reports_the_same_problems_as_encode():
    entry = PatternEntry(frequency=8.0, period=114.0, steps=4)
    with pytest.raises(ValueError, match=r"PatternEntry needs exactly one of frequency .* and period .* > 0"):
        entry.validate()
    PatternEntry(period=114.0, steps=4).validate()  # no error


def test_inline_sequence_items_are_checked():
    frames = [bytes(frame) for frame in encode("/info", CameraInfo(k=np.arange(9.0)))]
    header = _header_of(frames)
    header["fields"]["k"][4] = "1"
    with pytest.raises(DecodeError, match=r"CameraInfo.k\[4\] must be float64; got str '1'"):
        decode(_with_header(frames, header))
    header["fields"]["k"] = header["fields"]["k"][:8]
    with pytest.raises(DecodeError, match=r"CameraInfo.k must be a list of 9 float64; got \[0.0, 1.0"):
        decode(_with_header(frames, header))


def test_nested_errors_say_where_the_message_sits():
    with pytest.raises(EncodeError, match=r"^cannot encode dptpu_msgs/msg/FringeFrame: FringeFrame.trigger: "
                                          r"Trigger.step must be < steps 4; got 4$"):
        encode("/t", FringeFrame(trigger=Trigger(steps=4, step=4)))
    with pytest.raises(EncodeError, match=r"^cannot encode dptpu_msgs/msg/Trigger: Trigger.step must be < steps 4; "
                                          r"got 4$"):
        encode("/t", Trigger(steps=4, step=4))
