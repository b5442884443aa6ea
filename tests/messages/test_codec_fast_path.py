"""The codec's fast paths accept and produce exactly what the general path does, and the header they write is
byte for byte the msgpack map of the wire specification: for flat types (scalars and arrays) and for types
with nested messages, message lists and sequences (every scanner message has a nested Header).

Each input is decoded twice, once as ``decode`` does (fast path first) and once by the general path alone
(``decoder.decode_checked``); both must give an equal message, or the same ``DecodeError`` text.
"""
from __future__ import annotations

import re

import msgpack
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dptpu.messages import (
    DecodeError,
    DecodeLimits,
    EncodeError,
    Header,
    Message,
    Time,
    decode,
    encode,
)
from dptpu.messages.decode_limits import DEFAULT_LIMITS
from dptpu.messages.decoder import decode_checked
from dptpu.messages.encoder import encode_checked
from dptpu.messages.fast_decoding import decode_well_formed
from dptpu.messages.registry import is_registered, lookup
from dptpu.messages.schema import array, message, nested, nested_list, scalar, sequence

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


def _nested_types():
    if is_registered("dptpu_test/msg/NestedSample"):
        return lookup("dptpu_test/msg/Part"), lookup("dptpu_test/msg/NestedSample")

    @message("dptpu_test/msg/Part", version=1)
    class Part(Message):
        name: str = scalar("string")
        weights: np.ndarray = array("float32", ("N",))

        def check_consistency(self) -> None:
            if self.name == "bad":
                raise ValueError("Part.name must not be 'bad'")

    @message("dptpu_test/msg/NestedSample", version=2)
    class NestedSample(Message):
        header: Header = nested(Header)
        seq: int = scalar("uint16")
        gains: np.ndarray = sequence("float64", 3)
        parts: list = nested_list(Part)
        depth_mm: np.ndarray = array("float32", ("H", "W"))

    return Part, NestedSample


Part, NestedSample = _nested_types()


def _sample(height=3, width=4) -> Message:
    return FlatSample(seq=7, gain=1.5, valid=True, label="cam0",
                      depth_mm=np.arange(height * width, dtype=np.float32).reshape(height, width),
                      mask=np.arange(5, dtype=np.uint8))


def _nested_sample(height=2, width=3, parts=2) -> Message:
    return NestedSample(header=Header(stamp=Time(sec=5, nanosec=6), frame_id="cam"), seq=9,
                        gains=np.array([1.0, 0.5, 0.25]),
                        parts=[Part(name=f"p{i}", weights=np.full(i + 1, i, np.float32)) for i in range(parts)],
                        depth_mm=np.arange(height * width, dtype=np.float32).reshape(height, width))


def _same_outcome(frames, **kwargs):
    """Decode with and without the fast path; assert the same message or the same DecodeError."""
    try:
        fast = decode(frames, **kwargs)
    except DecodeError as error:
        fast = ("error", str(error))
    try:
        general = decode_checked(frames, **kwargs)
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
    assert decode_well_formed(frames, FlatSample, DEFAULT_LIMITS) is not None  # the fast path took it


def test_nested_message_encodes_like_the_general_path_and_decodes_on_the_fast_path():
    msg = _nested_sample()
    frames = encode("/nested", msg)
    assert frames[1] == encode_checked("/nested", msg)[1]  # the same header, byte for byte
    header = msgpack.unpackb(frames[1], ext_hook=msgpack.ExtType)
    assert header["fields"]["parts"][1] == {"name": "p1", "weights": msgpack.ExtType(1, b"\0\0\0\1")}
    assert header["arrays"] == [["<f4", [1]], ["<f4", [2]], ["<f4", [2, 3]]]  # depth first, in field order
    frames = [bytes(frame) for frame in frames]
    _topic, decoded = _same_outcome(frames, expected_type=NestedSample)
    assert decoded == msg and decoded.header.stamp.nanosec == 6 and decoded.parts[1].weights.tolist() == [1.0, 1.0]
    assert decode_well_formed(frames, NestedSample, DEFAULT_LIMITS) is not None  # the fast path took it


def test_nested_fast_encode_falls_back_and_raises_the_general_paths_error():
    msg = _nested_sample()
    msg.parts[0].name = "bad"  # a nested check_consistency fails: the general path names where
    with pytest.raises(EncodeError, match=r"NestedSample.parts\[0\]: Part.name must not be 'bad'"):
        encode("/nested", msg)
    msg = _nested_sample()
    msg.gains = [1, 2, 3]  # a list of ints: converted by the general path
    assert encode("/nested", msg)[1] == encode("/nested", _nested_sample())[1].replace(
        msgpack.packb([1.0, 0.5, 0.25]), msgpack.packb([1.0, 2.0, 3.0]))


@pytest.mark.parametrize("change, match", [
    (lambda h: h["fields"]["header"]["stamp"].update(nanosec=10**9), "nanosec"),
    (lambda h: h["fields"]["parts"][0].update(name="bad"), r"parts\[0\]: Part.name must not be 'bad'"),
    (lambda h: h["fields"]["parts"].append(h["fields"]["parts"][0]), "already uses"),
    (lambda h: h["fields"]["parts"].pop(), r"array frame\(s\) \[1\] are not referenced"),
    (lambda h: h["fields"].update(gains=[1.0, 2.0]), "gains must be a list of 3 float64"),
    (lambda h: h["fields"].update(gains=[1.0, 2.0, 3]), r"gains\[2\] must be float64"),
    (lambda h: h["fields"]["header"].update(extra=1), "header: fields do not match"),
])
def test_malformed_nested_headers_get_the_general_paths_error(change, match):
    frames = [bytes(frame) for frame in encode("/nested", _nested_sample())]
    header = msgpack.unpackb(frames[1], ext_hook=msgpack.ExtType)
    change(header)
    frames[1] = msgpack.packb(header, use_bin_type=True)
    outcome = _same_outcome(frames, limits=LIMITS)
    assert outcome[0] == "error" and re.search(match, outcome[1]), outcome


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


def _nested_targets(fields: dict) -> list:
    """Every map of a nested header's fields that a change may hit: the top level, the header, its stamp, the parts."""
    targets = [fields]
    if isinstance(fields.get("header"), dict):
        targets.append(fields["header"])
        if isinstance(fields["header"].get("stamp"), dict):
            targets.append(fields["header"]["stamp"])
    if isinstance(fields.get("parts"), list):
        targets.extend(part for part in fields["parts"] if isinstance(part, dict))
    return targets


@FUZZ
@given(data=st.data())
def test_random_changes_to_nested_messages_give_the_same_outcome_with_and_without_the_fast_path(data):
    msg = _nested_sample(data.draw(st.integers(0, 2)), 3, data.draw(st.integers(0, 3)))
    frames = [bytes(frame) for frame in encode("/nested", msg)]
    header = msgpack.unpackb(frames[1], ext_hook=msgpack.ExtType)
    for _ in range(data.draw(st.integers(1, 3))):
        where = data.draw(st.sampled_from(["field", "descriptor", "frames", "drop_field"]))
        if where == "frames":
            index = data.draw(st.integers(0, len(frames) - 1))
            frames[index] = frames[index][:data.draw(st.integers(0, len(frames[index])))]
            continue
        if where == "descriptor":
            if header["arrays"]:
                descriptor = header["arrays"][data.draw(st.integers(0, len(header["arrays"]) - 1))]
                descriptor[data.draw(st.integers(0, 1))] = data.draw(VALUES | st.sampled_from(["<f4", "|u1", "<f8"]))
            continue
        target = data.draw(st.sampled_from(_nested_targets(header["fields"])))
        keys = sorted(str(key) for key in target)
        if where == "field":
            target[data.draw(st.sampled_from(keys + ["extra"]))] = data.draw(VALUES | st.just({}) | st.just([{}]))
        elif keys:
            del target[data.draw(st.sampled_from(keys))]
    frames[1] = msgpack.packb(header, use_bin_type=True)
    _same_outcome(frames, limits=LIMITS, expected_type=data.draw(st.sampled_from([None, NestedSample])))
