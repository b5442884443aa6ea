"""Every message type in ROS 2 CDR (messages.cdr) and its ROS 2 form (messages.ros2_definitions): bit-exact round
trips, the same bytes as mcap-ros2-support's encoder for the ROS types, the scanner types read back by
mcap-ros2-support's own decoder from the ros2msg schema, and the shipped .msg files."""
from __future__ import annotations

import numpy as np
import pytest
from mcap.records import Schema
from mcap_ros2._dynamic import serialize_dynamic
from mcap_ros2.decoder import DecoderFactory

from dptpu.messages import AbsolutePhase, Image, PhaseMaps, registered_types
from dptpu.messages.cdr import CDR_LE_HEADER, decode_cdr, encode_cdr
from dptpu.messages.ros2_definitions import msg_files, ros2_message_definition, shipped_msg_file
from tests.messages.test_codec_roundtrip import sample_messages

SAMPLES = sample_messages()


@pytest.mark.parametrize("msg", SAMPLES, ids=lambda m: type(m).__name__)
def test_cdr_round_trip_is_bit_exact(msg):
    data = encode_cdr(msg)
    assert data[:4] == CDR_LE_HEADER
    assert decode_cdr(type(msg), data) == msg


@pytest.mark.parametrize("msg", [m for m in SAMPLES if not type(m).TYPE_NAME.startswith("dptpu_msgs/")],
                         ids=lambda m: type(m).__name__)
def test_ros_types_are_the_bytes_of_mcap_ros2s_encoder(msg):
    from dptpu.tools.recording.ros2_cdr import to_ros2_dict

    name = type(msg).TYPE_NAME
    encode = serialize_dynamic(name, ros2_message_definition(type(msg)))[name]
    assert bytes(encode(to_ros2_dict(msg))) == encode_cdr(msg)


@pytest.mark.parametrize("msg", [m for m in SAMPLES if type(m).TYPE_NAME.startswith("dptpu_msgs/")],
                         ids=lambda m: type(m).__name__)
def test_scanner_types_are_read_by_mcap_ros2s_decoder_from_their_schema(msg):
    """An independent CDR reader (what Foxglove and rosbag2 tools do) gets every field from the schema text."""
    cls = type(msg)
    schema = Schema(id=1, name=cls.TYPE_NAME, encoding="ros2msg", data=ros2_message_definition(cls).encode())
    decoded = DecoderFactory().decoder_for("cdr", schema)(encode_cdr(msg))
    if hasattr(msg, "header"):
        assert (decoded.header.stamp.sec, decoded.header.frame_id) == (msg.header.stamp.sec, msg.header.frame_id)
    if isinstance(msg, PhaseMaps):
        assert (decoded.height, decoded.width) == msg.valid.shape
        assert np.array_equal(np.array(decoded.phases, np.float32).reshape(msg.phases.shape), msg.phases)
        assert np.array_equal(np.array(decoded.valid, bool).reshape(msg.valid.shape), msg.valid)
    if isinstance(msg, AbsolutePhase):
        assert np.array_equal(np.array(decoded.fringe_order, np.int32).reshape(msg.fringe_order.shape),
                              msg.fringe_order)
        assert decoded.method == msg.method


def test_a_record_that_does_not_fit_its_type_is_refused_naming_the_field():
    image = next(m for m in SAMPLES if isinstance(m, Image))
    data = encode_cdr(image)
    with pytest.raises(ValueError, match=r"Image.data: the record ends after"):
        decode_cdr(Image, data[:-10])
    phase = next(m for m in SAMPLES if isinstance(m, PhaseMaps))
    data = bytearray(encode_cdr(phase))
    with pytest.raises(ValueError, match="not little-endian plain CDR"):
        decode_cdr(PhaseMaps, b"\x00\x00\x00\x00" + bytes(data[4:]))


def test_the_shipped_msg_files_are_the_scanner_types_ros2_form():
    files = msg_files()
    scanner = {name.rsplit("/", 1)[1] + ".msg" for name in registered_types() if name.startswith("dptpu_msgs/")}
    assert set(files) == scanner
    for name, text in files.items():
        assert shipped_msg_file(name) == text, f"messages/msg/{name} is stale: write msg_files() again"


def test_an_empty_stack_of_planes_round_trips():
    """A (F, H, W) array whose planes are empty (every default message has one) is written as 0 elements and
    read back as the empty array, not refused for its 0-element planes."""
    empty = PhaseMaps()
    assert empty.phases.size == 0
    back = decode_cdr(PhaseMaps, encode_cdr(empty))
    assert back.phases.shape == empty.phases.shape and back == empty
