"""The codec's fast paths (flat types: scalars and arrays only) accept and produce exactly what the general
path does, and the header they write is byte for byte the msgpack map of the wire specification.

Each input is decoded twice, once as ``decode`` does (fast path first) and once with the fast path switched
off; both must give an equal message, or the same ``DecodeError`` text.
"""
from __future__ import annotations

import re

import msgpack
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dptpu.messages import DecodeError, DecodeLimits, Message, codec, decode, encode
from dptpu.messages.registry import is_registered, lookup
from dptpu.messages.schema import array, message, scalar

LIMITS = DecodeLimits(max_frames=8, max_total_bytes=1 << 16, max_array_bytes=1 << 12, max_header_bytes=2048)
FUZZ = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def _flat_type():
    if is_registered("dptpu_test/msg/FlatSample"):
        return lookup("dptpu_test/msg/FlatSample")

    @message("dptpu_test/msg/FlatSample", version=3)
    class FlatSample(Message):
        seq: int = scalar("uint32")
        gain: float = scalar("float64")
        valid: bool = scalar("bool")
        label: str = scalar("string")
        depth_mm: np.ndarray = array("float32", ("H", "W"))
        mask: np.ndarray = array("uint8", ("N",))

    return FlatSample


FlatSample = _flat_type()


def _sample(height=3, width=4) -> Message:
    return FlatSample(seq=7, gain=1.5, valid=True, label="cam0",
                      depth_mm=np.arange(height * width, dtype=np.float32).reshape(height, width),
                      mask=np.arange(5, dtype=np.uint8))


def _general_only(frames, **kwargs):
    saved = codec._decode_well_formed
    codec._decode_well_formed = lambda *args: None
    try:
        return decode(frames, **kwargs)
    finally:
        codec._decode_well_formed = saved


def _same_outcome(frames, **kwargs):
    """Decode with and without the fast path; assert the same message or the same DecodeError."""
    try:
        fast = decode(frames, **kwargs)
    except DecodeError as error:
        fast = ("error", str(error))
    try:
        general = _general_only(frames, **kwargs)
    except DecodeError as error:
        general = ("error", str(error))
    assert type(fast[1]) is type(general[1]) and fast == general
    return fast


def test_header_is_the_packed_map_of_the_specification():
    msg = _sample()
    frames = encode("/flat", msg)
    header = {"wire": 1, "type": "dptpu_test/msg/FlatSample", "version": 3,
              "fields": {"seq": 7, "gain": 1.5, "valid": True, "label": "cam0",
                         "depth_mm": msgpack.ExtType(1, b"\0\0\0\0"), "mask": msgpack.ExtType(1, b"\0\0\0\1")},
              "arrays": [["<f4", [3, 4]], ["|u1", [5]]]}
    assert frames[1] == msgpack.packb(header, use_bin_type=True)
    assert [bytes(frame) for frame in frames[2:]] == [msg.depth_mm.tobytes(), msg.mask.tobytes()]


def test_fast_encode_falls_back_for_numpy_scalars_and_big_endian_arrays():
    msg = _sample()
    msg.seq = np.uint32(7)  # not an int: the general path converts it
    msg.depth_mm = msg.depth_mm.astype(">f4")  # big-endian: one copy into little-endian
    frames = encode("/flat", msg)
    assert frames[1] == encode("/flat", _sample())[1]
    assert bytes(frames[2]) == _sample().depth_mm.tobytes()


def test_well_formed_message_decodes_to_read_only_views_of_its_frames():
    frames = [bytes(frame) for frame in encode("/flat", _sample())]
    topic, msg = _same_outcome(frames, expected_type=FlatSample)
    assert topic == "/flat" and msg == _sample()
    assert not msg.depth_mm.flags.writeable and not msg.mask.flags.writeable
    assert np.shares_memory(msg.depth_mm, np.frombuffer(frames[2], np.uint8))  # viewed, not copied
    assert codec._decode_well_formed(frames, FlatSample, codec.DEFAULT_LIMITS) is not None  # the fast path took it


@pytest.mark.parametrize("change, match", [
    (lambda h: h["fields"].update(seq=2**32), "FlatSample.seq must be uint32"),
    (lambda h: h["fields"].update(valid=1), "FlatSample.valid must be bool"),
    (lambda h: h["fields"].update(label=msgpack.ExtType(1, b"\0\0\0\0")), "FlatSample.label must be string"),
    (lambda h: h["fields"].update(seq=msgpack.ExtType(5, b"\0\0\0\0")), "extension type 5"),
    (lambda h: h["fields"].update(mask=msgpack.ExtType(1, b"\0\0\0\0")), "already uses"),
    (lambda h: h["fields"].update(mask=msgpack.ExtType(1, b"\0\0\0")), "4-byte index"),
    (lambda h: h["arrays"][1].__setitem__(0, "<u2"), r"shape \[5\] of <u2 needs 10 bytes"),
    (lambda h: h.update(version=2), "schema version mismatch"),
])
def test_malformed_headers_get_the_general_paths_error(change, match):
    frames = [bytes(frame) for frame in encode("/flat", _sample())]
    header = msgpack.unpackb(frames[1], ext_hook=msgpack.ExtType)
    change(header)
    frames[1] = msgpack.packb(header, use_bin_type=True)
    outcome = _same_outcome(frames, limits=LIMITS)
    assert outcome[0] == "error" and re.search(match, outcome[1]), outcome


VALUES = st.none() | st.booleans() | st.integers(-2, 2**33) | st.floats(allow_nan=False) | st.text(max_size=6) \
    | st.binary(max_size=6) | st.builds(msgpack.ExtType, st.integers(0, 3), st.binary(max_size=5)) \
    | st.lists(st.integers(-1, 20), max_size=3)


@FUZZ
@given(data=st.data())
def test_random_changes_give_the_same_outcome_with_and_without_the_fast_path(data):
    frames = [bytes(frame) for frame in encode("/flat", _sample(data.draw(st.integers(0, 3)), 4))]
    header = msgpack.unpackb(frames[1], ext_hook=msgpack.ExtType)
    for _ in range(data.draw(st.integers(1, 3))):
        where = data.draw(st.sampled_from(["field", "descriptor", "frames", "drop_field"]))
        if where == "field":
            header["fields"][data.draw(st.sampled_from(sorted(header["fields"]) + ["extra"]))] = data.draw(VALUES)
        elif where == "descriptor":
            descriptor = header["arrays"][data.draw(st.integers(0, 1))]
            descriptor[data.draw(st.integers(0, 1))] = data.draw(VALUES | st.sampled_from(["<f4", "|u1", "<f8"]))
        elif where == "frames":
            index = data.draw(st.integers(0, len(frames) - 1))
            frames[index] = frames[index][:data.draw(st.integers(0, len(frames[index])))]
        elif header["fields"]:
            del header["fields"][data.draw(st.sampled_from(sorted(header["fields"])))]
    if data.draw(st.booleans()):  # last, as it may replace the maps changed above
        header[data.draw(st.sampled_from(["wire", "type", "version", "fields", "arrays"]))] = data.draw(VALUES)
    frames[1] = msgpack.packb(header, use_bin_type=True)
    _same_outcome(frames, limits=LIMITS, expected_type=data.draw(st.sampled_from([None, FlatSample])))
