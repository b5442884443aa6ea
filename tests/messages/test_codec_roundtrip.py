"""Round trips of every message type through the wire codec: bit-exact, zero-copy, read-only views."""

from __future__ import annotations

import numpy as np
import pytest
import zmq

from dptpu.messages import (
    AbsolutePhase,
    CameraInfo,
    DiagnosticArray,
    DiagnosticStatus,
    FringeBurst,
    FringeFrame,
    Header,
    Image,
    KeyValue,
    PatternEntry,
    PatternSequence,
    PhaseMaps,
    PointCloud2,
    PointField,
    Quaternion,
    RegionOfInterest,
    ScanStatus,
    TFMessage,
    Time,
    Transform,
    TransformStamped,
    Trigger,
    TriggerBurst,
    Vector3,
    decode,
    encode,
    registered_types,
)
from dptpu.messages.schema import ARRAY

TOPIC = "/scanner/test"


def _address(buffer) -> int:
    """Address of the first byte of any buffer (bytes, memoryview, ndarray)."""
    return np.frombuffer(buffer, dtype=np.uint8).__array_interface__["data"][0]


def sample_messages() -> list:
    """One or more filled-in messages of every registered type (seeded; small images)."""
    rng = np.random.default_rng(0)
    stamp = Time(sec=1_700_000_000, nanosec=123_456_789)
    header = Header(stamp=stamp, frame_id="scanner_optical_frame")
    mono8 = Image.from_array(rng.integers(0, 256, (48, 64), dtype=np.uint8), header=header)
    mono16 = Image.from_array(rng.integers(0, 4096, (48, 64), dtype=np.uint16), header=header)
    depth = Image.from_array(rng.normal(0.5, 0.1, (48, 64)).astype(np.float32), header=header)
    rgb = Image.from_array(rng.integers(0, 256, (12, 16, 3), dtype=np.uint8), "rgb8", header=header)
    roi = RegionOfInterest(x_offset=8, y_offset=4, height=32, width=48, do_rectify=True)
    camera_info = CameraInfo.from_intrinsics([[1200.0, 0.0, 319.5], [0.0, 1201.0, 239.5], [0.0, 0.0, 1.0]],
                                             [-0.12, 0.05, 1e-4, -2e-4, 0.01], 640, 480, header=header)
    camera_info.binning_x, camera_info.binning_y, camera_info.roi = 2, 2, roi
    xyzq = rng.normal(0.0, 1.0, (24, 32, 5)).astype(np.float32)
    xyzq[3:7, 10:20, :3] = np.nan  # holes of an organized cloud
    cloud = PointCloud2.from_array(xyzq, ("x", "y", "z", "intensity", "quality"), header=header)
    mixed_dtype = np.dtype({"names": ["x", "y", "z", "rgb", "ring", "t"],
                            "formats": ["<f4", "<f4", "<f4", ("u1", (3,)), "<u2", "<f8"],
                            "offsets": [0, 4, 8, 12, 16, 24], "itemsize": 32})
    mixed = np.zeros((5, 7), dtype=mixed_dtype)
    mixed["x"] = rng.normal(size=(5, 7))
    mixed["rgb"] = rng.integers(0, 256, (5, 7, 3))
    mixed["ring"] = np.arange(5)[:, None]
    mixed["t"] = rng.random((5, 7))
    mixed_cloud = PointCloud2.from_structured(mixed, header=header)
    entries = [PatternEntry(frequency=96.0, steps=12), PatternEntry(period=83.5, steps=4, phase_offset=0.25),
               PatternEntry(frequency=1.0, steps=12)]
    sequence = PatternSequence(header=header, entries=entries, fringe_axis="x", projector_width=912,
                               projector_height=1140, shift_sign=-1)
    trigger = Trigger(header=header, sequence_id=41, pattern_index=13, pattern_count=28, frequency=96.0 / 8.3,
                      steps=4, step=1)
    frame = FringeFrame(image=mono8, trigger=trigger)
    burst_triggers = [Trigger(header=header, sequence_id=41, pattern_index=13 + k, pattern_count=28,
                              frequency=96.0 / 8.3, steps=4, step=k) for k in range(3)]
    trigger_burst = TriggerBurst(header=header, triggers=burst_triggers)
    burst = FringeBurst.from_frames(rng.integers(0, 4096, (3, 8, 5), dtype=np.uint16), burst_triggers, header=header)
    phases = rng.uniform(0, 2 * np.pi, (3, 24, 32)).astype(np.float32)
    phase_maps = PhaseMaps(header=header, sequence_id=41, fringe_axis="x", projector_width=912,
                           projector_height=1140, frequencies=np.array([96.0, 912 / 83.5, 1.0]), phases=phases,
                           modulation=rng.uniform(0, 80, (3, 24, 32)).astype(np.float32),
                           valid=rng.random((24, 32)) > 0.2)
    absolute = AbsolutePhase(header=header, sequence_id=41, frequency=96.0, fringe_axis="y", projector_width=912,
                             projector_height=1140,
                             absolute_phase=rng.uniform(0, 2 * np.pi * 96, (24, 32)).astype(np.float32),
                             fringe_order=rng.integers(0, 96, (24, 32), dtype=np.int32),
                             valid=rng.random((24, 32)) > 0.1,
                             reliability=rng.random((24, 32)).astype(np.float32), method="nt")
    status = ScanStatus(header=header, sequence_id=41, level=ScanStatus.WARN, state="done",
                        reason="3 frames dropped", node="/scanner/phase", frames_expected=28, frames_received=25,
                        frames_dropped=3, decode_errors=1, valid_pixels=700, total_pixels=768, duration_s=0.42)
    field = PointField(name="intensity", offset=12, datatype=PointField.FLOAT32, count=1)
    key_value = KeyValue(key="latency_ms", value="31.5")
    diagnostic = DiagnosticStatus(level=DiagnosticStatus.WARN, name="dptpu: scan", message="scan 41: UNTRUSTED",
                                  hardware_id="rig-7", values=[key_value, KeyValue(key="outcome", value="untrusted")])
    diagnostics = DiagnosticArray(header=header, status=[diagnostic, DiagnosticStatus(name="dptpu: /cloud")])
    translation = Vector3(x=0.012, y=-0.25, z=1.5)
    rotation = Quaternion(x=0.5, y=-0.5, z=0.5, w=0.5)
    transform = Transform(translation=translation, rotation=rotation)
    mount = TransformStamped(header=Header(stamp=stamp, frame_id="tool0"), child_frame_id="scanner_optical_frame",
                             transform=transform)
    tf = TFMessage(transforms=[mount, TransformStamped(header=header, child_frame_id="projector_optical_frame")])
    return [stamp, header, mono8, mono16, depth, rgb, roi, camera_info, field, cloud, mixed_cloud, entries[1],
            sequence, trigger, trigger_burst, frame, burst, phase_maps, absolute, status, key_value, diagnostic,
            diagnostics, translation, rotation, transform, mount, tf]


def _array_paths(msg, prefix=""):
    """(path, ndarray) of every bulk-array field of msg, nested ones included."""
    for spec in type(msg).FIELDS:
        value = getattr(msg, spec.name)
        if spec.kind == ARRAY:
            yield prefix + spec.name, value
        elif spec.kind == "message":
            yield from _array_paths(value, f"{prefix}{spec.name}.")


def test_samples_cover_every_registered_type():
    # Types registered by dptpu.messages itself (the graph runtime registers its own interfaces too).
    own = {name for name, cls in registered_types().items() if cls.__module__.startswith("dptpu.messages")}
    assert {type(msg).TYPE_NAME for msg in sample_messages()} == own


@pytest.mark.parametrize("msg", sample_messages(), ids=lambda m: type(m).__name__)
def test_round_trip_is_bit_exact_with_read_only_views_of_the_frames(msg):
    frames = encode(TOPIC, msg)
    received = [bytes(frame) for frame in frames]  # what the wire delivers
    topic, decoded = decode(received, expected_type=type(msg))

    assert topic == TOPIC
    assert type(decoded) is type(msg)
    assert decoded == msg
    original_arrays = dict(_array_paths(msg))
    decoded_arrays = dict(_array_paths(decoded))
    assert len(received) == 2 + len(decoded_arrays)
    for index, (path, values) in enumerate(decoded_arrays.items()):
        expected = original_arrays[path]
        assert values.dtype == expected.dtype and values.shape == expected.shape, path
        assert values.tobytes() == expected.tobytes(), path
        assert not values.flags.writeable, path
        assert _address(values) == _address(received[2 + index]), f"{path} is not a view of its frame"


def test_round_trip_keeps_nan_holes_and_stamps():
    cloud = next(m for m in sample_messages() if isinstance(m, PointCloud2) and len(m.fields) == 5)
    _, decoded = decode(encode(TOPIC, cloud))
    xyz = decoded.to_array(("x", "y", "z"))
    assert decoded.is_dense is False
    assert np.isnan(xyz[3:7, 10:20]).all() and np.isfinite(xyz[:3]).all()
    assert decoded.header.stamp.to_ns() == 1_700_000_000_123_456_789
    assert decoded.header.frame_id == "scanner_optical_frame"


def test_encode_is_zero_copy_for_contiguous_arrays():
    rng = np.random.default_rng(0)
    phases = rng.random((3, 24, 32)).astype(np.float32)
    modulation = rng.random((3, 24, 32)).astype(np.float32)
    valid = rng.random((24, 32)) > 0.5
    msg = PhaseMaps(frequencies=np.array([64.0, 8.0, 1.0]), phases=phases, modulation=modulation, valid=valid)
    frames = encode(TOPIC, msg)
    assert [_address(frame) for frame in frames[2:]] == [arr.ctypes.data for arr in (phases, modulation, valid)]
    assert [memoryview(frame).nbytes for frame in frames[2:]] == [phases.nbytes, modulation.nbytes, valid.nbytes]
    image_pixels = rng.integers(0, 256, (48, 64), dtype=np.uint8)
    image_frames = encode(TOPIC, Image.from_array(image_pixels))
    assert _address(image_frames[2]) == image_pixels.ctypes.data


def test_encode_copies_a_non_contiguous_array_once_into_c_order():
    rng = np.random.default_rng(0)
    full = rng.random((48, 64)).astype(np.float32)
    view = full[::2, ::2]  # (24, 32), strided
    msg = AbsolutePhase(absolute_phase=view, fringe_order=np.zeros((24, 32), np.int32),
                        valid=np.ones((24, 32), bool), reliability=np.ones((24, 32), np.float32))
    frames = encode(TOPIC, msg)
    assert _address(frames[2]) != full.ctypes.data
    _, decoded = decode(frames)
    np.testing.assert_array_equal(decoded.absolute_phase, view)
    assert decoded.absolute_phase.flags.c_contiguous


def test_encode_converts_big_endian_arrays_to_little_endian():
    values = np.arange(24 * 32, dtype=">f4").reshape(24, 32)
    msg = AbsolutePhase(absolute_phase=values, fringe_order=np.zeros((24, 32), ">i4"),
                        valid=np.ones((24, 32), bool), reliability=np.ones((24, 32), np.float32))
    _, decoded = decode(encode(TOPIC, msg))
    assert decoded.absolute_phase.dtype == np.dtype("<f4")
    assert decoded.fringe_order.dtype == np.dtype("<i4")
    np.testing.assert_array_equal(decoded.absolute_phase, values)


def test_decode_accepts_memoryviews_bytearrays_and_zmq_frames():
    msg = next(m for m in sample_messages() if isinstance(m, FringeFrame))
    frames = encode(TOPIC, msg)
    as_memoryviews = [memoryview(bytes(frame)) for frame in frames]
    as_bytearrays = [bytearray(frame) for frame in frames]
    as_zmq_frames = [zmq.Frame(bytes(frame)) for frame in frames]
    for received in (as_memoryviews, as_bytearrays, as_zmq_frames):
        _, decoded = decode(received)
        assert decoded == msg
        assert not decoded.image.data.flags.writeable  # even over writable buffers
        with pytest.raises(ValueError, match="read-only"):
            decoded.image.data[0] = 1


def test_zero_copy_through_a_real_zmq_socket_pair():
    msg = next(m for m in sample_messages() if isinstance(m, PhaseMaps))
    context = zmq.Context.instance()
    sender, receiver = context.socket(zmq.PAIR), context.socket(zmq.PAIR)
    try:
        receiver.bind("inproc://dptpu-messages-test")
        sender.connect("inproc://dptpu-messages-test")
        sender.send_multipart(encode("/scanner/phase", msg), copy=False)
        assert receiver.poll(2000)
        received = receiver.recv_multipart(copy=False)
    finally:
        sender.close(linger=0)
        receiver.close(linger=0)
    topic, decoded = decode(received, expected_type="dptpu_msgs/msg/PhaseMaps")
    assert topic == "/scanner/phase"
    assert decoded == msg
    assert _address(decoded.phases) == _address(received[2].buffer)


def test_inline_sequences_decode_as_writable_float64_arrays():
    info = next(m for m in sample_messages() if isinstance(m, CameraInfo))
    _, decoded = decode(encode(TOPIC, info))
    assert decoded.k.dtype == np.float64 and decoded.k.shape == (9,)
    assert decoded.k[0] == 1200.0 and decoded.k[4] == 1201.0 and decoded.k[2] == 319.5
    np.testing.assert_array_equal(decoded.d, [-0.12, 0.05, 1e-4, -2e-4, 0.01])
    decoded.k[0] = 1000.0  # a copy, so mutable like an rclpy message
    assert decoded.k[0] == 1000.0
    assert decoded.roi == RegionOfInterest(x_offset=8, y_offset=4, height=32, width=48, do_rectify=True)


def test_encode_accepts_numpy_scalars_and_sequences_as_lists():
    msg = Trigger(sequence_id=np.uint32(7), pattern_index=np.int64(2), pattern_count=12, frequency=np.float32(1.5),
                  steps=12, step=2)
    _, decoded = decode(encode(TOPIC, msg))
    assert (decoded.sequence_id, decoded.pattern_index, decoded.frequency) == (7, 2, 1.5)
    assert type(decoded.sequence_id) is int and type(decoded.frequency) is float
    info = CameraInfo(distortion_model="plumb_bob", d=[0.1, 0.0, 0.0, 0.0, 0.0], k=list(range(9)))
    _, decoded_info = decode(encode(TOPIC, info))
    np.testing.assert_array_equal(decoded_info.k, np.arange(9.0))


@pytest.mark.parametrize("type_name", sorted(set(registered_types()) - {"dptpu_msgs/msg/PatternEntry",
                                                                       "dptpu_msgs/msg/PatternSequence"}))
def test_default_constructed_messages_round_trip(type_name):
    """Like rclpy: construct empty, fill later. (A PatternEntry/PatternSequence needs its geometry first.)"""
    cls = registered_types()[type_name]
    _, decoded = decode(encode(TOPIC, cls()))
    assert decoded == cls()
    if cls is PointCloud2:
        assert decoded.to_structured().shape == (0, 0) and decoded.to_array().shape == (0, 0, 0)
