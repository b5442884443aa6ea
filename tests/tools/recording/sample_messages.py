"""Seeded sample messages of every registered type for the recording tests (small arrays)."""

from __future__ import annotations

import dataclasses

import numpy as np

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
    RegionOfInterest,
    ScanStatus,
    Time,
    Trigger,
    TriggerBurst,
)
from dptpu.messages.geometry import Quaternion, Transform, TransformStamped, Vector3
from dptpu.messages.tf import TFMessage

STAMP = Time(sec=1_700_000_000, nanosec=123_456_789)
HEADER = Header(stamp=STAMP, frame_id="scanner_optical_frame")


def sample_messages() -> dict[str, object]:
    """``{topic: message}``: one topic per case, every registered type at least once."""
    rng = np.random.default_rng(0)
    mono8 = Image.from_array(rng.integers(0, 256, (12, 16), dtype=np.uint8), header=HEADER)
    mono16_be = Image.from_array(rng.integers(0, 65536, (6, 9), dtype=np.uint16).astype(">u2"),
                                 header=Header(stamp=Time(sec=-2, nanosec=999_999_999), frame_id="cam"))
    depth = Image.from_array(rng.normal(0.5, 0.1, (10, 12)).astype(np.float32), header=HEADER)
    depth.data = np.array(depth.data)  # writable copy, then NaN holes written through a view
    depth.to_array()[2:4, 3:5] = np.nan
    rgb = Image.from_array(rng.integers(0, 256, (4, 5, 3), dtype=np.uint8), "rgb8", header=HEADER)
    padded_rows = rng.integers(0, 256, (5, 24), dtype=np.uint8)  # 20 bytes of mono16 pixels + 4 padding
    padded = Image(header=HEADER, height=5, width=10, encoding="mono16", is_bigendian=0, step=24,
                   data=padded_rows.reshape(-1))
    camera_info = CameraInfo.from_intrinsics([[1200.0, 0.0, 319.5], [0.0, 1201.0, 239.5], [0.0, 0.0, 1.0]],
                                             [-0.12, 0.05, 1e-4, -2e-4, 0.01], 640, 480, header=HEADER)
    camera_info.binning_x, camera_info.binning_y = 2, 2
    camera_info.roi = RegionOfInterest(x_offset=8, y_offset=4, height=32, width=48, do_rectify=True)
    xyz = rng.normal(0.0, 1.0, (6, 8, 4)).astype(np.float32)
    xyz[1:3, 2:5, :3] = np.nan
    cloud = PointCloud2.from_array(xyz, ("x", "y", "z", "intensity"), header=HEADER)
    mixed_dtype = np.dtype({"names": ["x", "y", "z", "rgb", "ring", "t"],
                            "formats": ["<f4", "<f4", "<f4", ("u1", (3,)), "<u2", "<f8"],
                            "offsets": [0, 4, 8, 12, 16, 24], "itemsize": 32})
    mixed = np.zeros((9,), dtype=mixed_dtype)
    mixed["x"] = rng.normal(size=9)
    mixed["rgb"] = rng.integers(0, 256, (9, 3))
    mixed["t"] = rng.random(9)
    unorganized = PointCloud2.from_structured(mixed, header=HEADER)
    entries = [PatternEntry(frequency=96.0, steps=12), PatternEntry(period=83.5, steps=4, phase_offset=0.25)]
    sequence = PatternSequence(header=HEADER, entries=entries, fringe_axis="x", projector_width=912,
                               projector_height=1140, shift_sign=-1)
    trigger = Trigger(header=HEADER, sequence_id=41, pattern_index=13, pattern_count=16, frequency=96.0 / 8.3,
                      steps=4, step=1)
    phases = rng.uniform(0, 2 * np.pi, (2, 6, 8)).astype(np.float32)
    phase_maps = PhaseMaps(header=HEADER, sequence_id=41, fringe_axis="x", projector_width=912,
                           projector_height=1140, frequencies=np.array([96.0, 912 / 83.5]), phases=phases,
                           modulation=rng.uniform(0, 80, (2, 6, 8)).astype(np.float32),
                           valid=rng.random((6, 8)) > 0.2)
    absolute = AbsolutePhase(header=HEADER, sequence_id=41, frequency=96.0, fringe_axis="y", projector_width=912,
                             projector_height=1140,
                             absolute_phase=rng.uniform(0, 2 * np.pi * 96, (6, 8)).astype(np.float32),
                             fringe_order=rng.integers(0, 96, (6, 8), dtype=np.int32),
                             valid=rng.random((6, 8)) > 0.1, reliability=rng.random((6, 8)).astype(np.float32),
                             method="nt")
    status = ScanStatus(header=HEADER, sequence_id=41, level=ScanStatus.WARN, state="processing",
                        reason="3 frames late", node="/scanner/phase", frames_expected=28, frames_received=27,
                        frames_dropped=1, decode_errors=2, valid_pixels=40, total_pixels=48, duration_s=0.731)
    return {
        "/camera/image_raw": mono8,
        "/camera/image_be": mono16_be,
        "/scanner/depth": depth,
        "/camera/image_rgb": rgb,
        "/camera/image_padded": padded,
        "/camera/camera_info": camera_info,
        "/scanner/points": cloud,
        "/scanner/points_unorganized": unorganized,
        "/projector/patterns": sequence,
        "/projector/trigger": trigger,
        "/camera/fringe": FringeFrame(image=mono8, trigger=trigger),
        "/camera/frame_bursts": FringeBurst.from_frames(
            rng.integers(0, 4096, (2, 5, 7), dtype=np.uint16),
            [trigger, dataclasses.replace(trigger, pattern_index=trigger.pattern_index + 1, step=trigger.step + 1)],
            header=HEADER),
        "/projector/trigger_bursts": TriggerBurst(header=trigger.header, triggers=[
            trigger, dataclasses.replace(trigger, pattern_index=trigger.pattern_index + 1, step=trigger.step + 1)]),
        "/scanner/phase": phase_maps,
        "/scanner/absolute_phase": absolute,
        "/scanner/status": status,
        "/debug/time": Time(sec=-5, nanosec=250_000_000),
        "/debug/header": Header(stamp=STAMP, frame_id="ünïcode frame"),
        "/debug/roi": RegionOfInterest(x_offset=1, y_offset=2, height=3, width=4, do_rectify=True),
        "/debug/point_field": PointField(name="x", offset=0, datatype=PointField.FLOAT32, count=1),
        "/debug/pattern_entry": PatternEntry(frequency=10.9, steps=3, phase_offset=-0.5),
        "/diagnostics": DiagnosticArray(header=HEADER, status=[DiagnosticStatus(
            level=DiagnosticStatus.WARN, name="dptpu: scan", message="scan 41: UNTRUSTED", hardware_id="rig-7",
            values=[KeyValue(key="wrong_share", value="0.0135")])]),
        "/debug/diagnostic_status": DiagnosticStatus(name="dptpu: /cloud"),
        "/debug/key_value": KeyValue(key="k", value="v"),
        "/debug/vector3": Vector3(x=1.5, y=-2.0, z=1e-9),
        "/debug/quaternion": Quaternion(x=0.5, y=0.5, z=0.5, w=0.5),
        "/debug/transform": Transform(translation=Vector3(z=0.25)),
        "/debug/transform_stamped": TransformStamped(header=HEADER, child_frame_id="projector"),
        "/tf_static": TFMessage(transforms=[TransformStamped(
            header=Header(stamp=STAMP, frame_id="tool0"), child_frame_id="scanner_optical_frame",
            transform=Transform(translation=Vector3(x=0.05, y=-0.01, z=0.1),
                                rotation=Quaternion(x=0.0, y=0.0, z=0.38268343236508984, w=0.9238795325112867)))]),
    }
