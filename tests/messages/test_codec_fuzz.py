"""Property-based fuzz of the decoder: random bytes, truncated frames, wrong dtypes, huge declared shapes.

Every input either decodes or raises DecodeError -- nothing else -- and decoding never allocates more
than a bounded amount of memory, however large the shapes it is told about (arrays are only viewed).
"""

from __future__ import annotations

import tracemalloc

import msgpack
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dptpu.messages import DecodeError, DecodeLimits, Message, decode, encode, registered_types

from .test_codec_roundtrip import sample_messages

LIMITS = DecodeLimits(max_frames=12, max_total_bytes=1 << 20, max_array_bytes=1 << 18, max_header_bytes=4096)
# Parsing a header of at most 4 KiB makes a few hundred KiB of Python objects at worst; 2 MiB is far
# above that and far below any array a hostile shape could ask for.
MAX_DECODE_ALLOCATION_BYTES = 2 << 20
FUZZ = settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])

SAMPLES = [(type(msg).__name__, [bytes(frame) for frame in encode("/fuzz", msg)]) for msg in sample_messages()
           if sum(memoryview(frame).nbytes for frame in encode("/fuzz", msg)) < 20_000]

DTYPE_NAMES = st.sampled_from(["|b1", "|u1", "<u2", "<u4", "<u8", "|i1", "<i2", "<i4", "<i8", "<f4", "<f8",
                               "|O", "O", ">f8", ">u2", "<U8", "|V16", "<c8", "<M8[s]", "float32", "", "<f16"])
DIMENSION = st.one_of(st.integers(0, 64), st.integers(-5, 2**64 - 1), st.sampled_from([2**31, 2**32, 2**63]))
MSGPACK_VALUES = st.recursive(
    st.none() | st.booleans() | st.integers(-(2**63), 2**64 - 1) | st.floats() | st.text(max_size=12)
    | st.binary(max_size=12),
    lambda children: st.lists(children, max_size=4) | st.dictionaries(st.text(max_size=10), children, max_size=4),
    max_leaves=12)


def _decode_or_decode_error(frames):
    """Decode under tracemalloc; return the message or None; anything but DecodeError fails the test."""
    tracemalloc.start()  # traces only the decode call (hypothesis' own allocations stay untraced)
    try:
        topic, msg = decode(frames, limits=LIMITS)
    except DecodeError:
        topic, msg = None, None
    finally:
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    if msg is not None:
        assert isinstance(topic, str) and isinstance(msg, Message)
        assert type(msg).TYPE_NAME in registered_types()
    assert peak < MAX_DECODE_ALLOCATION_BYTES, f"decode allocated {peak} bytes"
    return msg


@FUZZ
@given(st.lists(st.binary(max_size=96), max_size=14))
def test_random_bytes_in_every_frame(frames):
    _decode_or_decode_error(frames)


@FUZZ
@given(sample=st.sampled_from(SAMPLES), data=st.data())
def test_mutated_valid_messages(sample, data):
    _, frames = sample
    frames = list(frames)
    mutation = data.draw(st.sampled_from(["truncate", "flip", "drop", "duplicate", "append", "splice"]))
    index = data.draw(st.integers(0, len(frames) - 1))
    frame = frames[index]
    if mutation == "truncate":
        frames[index] = frame[:data.draw(st.integers(0, max(0, len(frame) - 1)))]
    elif mutation == "flip" and frame:
        position = data.draw(st.integers(0, len(frame) - 1))
        value = data.draw(st.integers(0, 255))
        frames[index] = frame[:position] + bytes([value]) + frame[position + 1:]
    elif mutation == "drop":
        del frames[index]
    elif mutation == "duplicate":
        frames.insert(index, frame)
    elif mutation == "append":
        frames.append(data.draw(st.binary(max_size=64)))
    else:
        frames[index] = data.draw(st.binary(max_size=64))
    msg = _decode_or_decode_error(frames)
    if mutation in ("drop", "duplicate", "append"):
        assert msg is None  # frame count no longer matches the header


@FUZZ
@given(sample=st.sampled_from(SAMPLES), data=st.data())
def test_forged_headers_with_wrong_dtypes_huge_shapes_and_random_fields(sample, data):
    _, frames = sample
    header = msgpack.unpackb(frames[1], ext_hook=msgpack.ExtType)
    arrays = header["arrays"]
    what = data.draw(st.sampled_from(["dtype", "shape", "fields", "type", "version", "key"]))
    if what == "dtype" and arrays:
        arrays[data.draw(st.integers(0, len(arrays) - 1))][0] = data.draw(DTYPE_NAMES)
    elif what == "shape" and arrays:
        arrays[data.draw(st.integers(0, len(arrays) - 1))][1] = data.draw(st.lists(DIMENSION, max_size=10))
    elif what == "fields":
        name = data.draw(st.sampled_from(sorted(header["fields"])))
        header["fields"][name] = data.draw(MSGPACK_VALUES)
    elif what == "type":
        header["type"] = data.draw(st.sampled_from(sorted(registered_types())) | st.text(max_size=20))
    elif what == "version":
        header["version"] = data.draw(MSGPACK_VALUES)
    else:
        header[data.draw(st.text(max_size=8))] = data.draw(MSGPACK_VALUES)
    forged = [frames[0], msgpack.packb(header, use_bin_type=True), *frames[2:]]
    _decode_or_decode_error(forged)


@FUZZ
@given(dtype=DTYPE_NAMES, shape=st.lists(DIMENSION, max_size=10), payload=st.binary(max_size=64))
def test_huge_declared_shapes_never_allocate(dtype, shape, payload):
    header = {"wire": 1, "type": "sensor_msgs/msg/Image", "version": 1,
              "fields": {"header": {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": ""}, "height": 1, "width": 1,
                         "encoding": "mono8", "is_bigendian": 0, "step": 1,
                         "data": msgpack.ExtType(1, b"\x00\x00\x00\x00")},
              "arrays": [[dtype, shape]]}
    msg = _decode_or_decode_error([b"/fuzz", msgpack.packb(header, use_bin_type=True), payload])
    if msg is not None:  # only a 1-byte uint8 image is consistent with these fields
        assert (dtype, shape, len(payload)) == ("|u1", [1], 1)
        assert msg.data.tolist() == list(payload)


def test_every_sample_decodes_unmodified():
    for name, frames in SAMPLES:
        assert _decode_or_decode_error(frames) is not None, name
    assert len(SAMPLES) >= 12
    assert np.dtype(np.uint8).str == "|u1"  # the allow-list is written in numpy's dtype.str spelling


def test_the_allocation_probe_sees_array_buffers():
    tracemalloc.start()
    try:
        buffer = np.zeros(MAX_DECODE_ALLOCATION_BYTES, np.uint8)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert buffer.nbytes <= peak  # so a decoder that allocated its arrays would fail the fuzz


def test_worst_case_header_parse_allocation_is_bounded_by_max_header_bytes():
    limits = DecodeLimits()  # 64 KiB headers
    count = limits.max_header_bytes - 5
    worst = b"\xdd" + count.to_bytes(4, "big") + b"\x80" * count  # a list of 65531 empty maps
    tracemalloc.start()
    try:
        with pytest.raises(DecodeError, match="header must be a msgpack map; got list"):
            decode([b"/fuzz", worst], limits=limits)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 80 * limits.max_header_bytes  # the bound documented on DecodeLimits
