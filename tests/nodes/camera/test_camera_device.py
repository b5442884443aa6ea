"""The GenICam camera wrapper on the real simulated GenTL producers, and the trigger/frame pairing rules.

``viky.cti`` ships in the genicam wheel (always here); ``TLSimu.cti`` in the genicam2 wheel (skipped
when that wheel is not installed).
"""

from __future__ import annotations

import numpy as np
import pytest

from dptpu.messages import Trigger
from dptpu.nodes.camera.genicam_acquisition import FramePairer
from dptpu.nodes.camera.genicam_device import (
    CameraSettings,
    CameraUnavailable,
    GenICamDevice,
    buffer_to_array,
    list_devices,
)
from dptpu.nodes.camera.genicam_producers import default_cti_paths, shipped_producer, split_cti_paths

VIKY = shipped_producer("viky.cti")
TLSIMU = shipped_producer("TLSimu.cti")
needs_tlsimu = pytest.mark.skipif(TLSIMU is None, reason="TLSimu.cti needs the genicam2 wheel (pip install genicam2)")


def test_viky_is_the_default_producer_and_lists_three_devices():
    assert VIKY is not None and VIKY.name == "viky.cti"
    assert default_cti_paths() == [VIKY] == split_cti_paths("")
    devices = list_devices([VIKY])
    assert [(d["serial"], d["model"], d["id"]) for d in devices] == [
        ("0", "Viky", "VikyTL_DEV_red"), ("1", "Viky", "VikyTL_DEV_green"), ("2", "Viky", "VikyTL_DEV_blue")]
    with pytest.raises(ValueError, match="must be GenTL producer files ending in .cti"):
        split_cti_paths("/opt/camera.so")


def test_viky_free_running_frames_show_a_20px_square_moving_one_pixel_per_frame():
    device = GenICamDevice.open(CameraSettings((VIKY,), serial="2", width=160, height=120,
                                               trigger_mode="free-running", frame_rate_hz=50.0, exposure_us=5000.0))
    try:
        assert (device.width, device.height, device.info["serial"]) == (160, 120, "2")
        assert device.notes == ["the camera has no ExposureTime feature: exposure_us 5000.0 ignored"]
        frames = [device.fetch(2.0) for _ in range(4)]
    finally:
        device.close()
    centroids = []
    for frame, stamp_ns in frames:
        assert frame.shape == (120, 160) and frame.dtype == np.uint8 and stamp_ns > 0
        assert set(np.unique(frame)) == {0, 255}
        rows, cols = np.nonzero(frame == 0)
        assert rows.size == 20 * 20 and np.ptp(rows) == np.ptp(cols) == 19  # one 20x20 black square
        centroids.append((cols.mean(), rows.mean()))
    steps = np.abs(np.diff(np.array(centroids), axis=0))  # (3, 2)
    assert np.all(steps == 1.0)  # the square moves one pixel along x and y each frame


def test_viky_refuses_trigger_modes_and_sizes_it_cannot_do():
    with pytest.raises(CameraUnavailable, match="trigger_mode software needs the TriggerMode and TriggerSource"):
        GenICamDevice.open(CameraSettings((VIKY,), trigger_mode="software"))
    with pytest.raises(CameraUnavailable, match=r"width 99 is not possible: the camera takes 100..800"):
        GenICamDevice.open(CameraSettings((VIKY,), width=99, trigger_mode="free-running"))
    with pytest.raises(CameraUnavailable, match="no camera with serial 'x' among the 3 found by viky.cti: 0, 1, 2"):
        GenICamDevice.open(CameraSettings((VIKY,), serial="x", trigger_mode="free-running"))
    with pytest.raises(CameraUnavailable, match="GenTL producer /nonexistent/p.cti does not exist"):
        GenICamDevice.open(CameraSettings(("/nonexistent/p.cti",)))
    with pytest.raises(ValueError, match="trigger_mode must be one of hardware, software, free-running"):
        CameraSettings((VIKY,), trigger_mode="sometimes")
    with pytest.raises(ValueError, match="pixel_format must be one of Mono8, Mono10, Mono12, Mono16"):
        CameraSettings((VIKY,), pixel_format="RGBa8")


@needs_tlsimu
def test_tlsimu_software_trigger_gives_exactly_one_frame_per_trigger():
    device = GenICamDevice.open(CameraSettings((TLSIMU,), serial="SN_InterfaceA_0", width=160, height=120,
                                               trigger_mode="software"))
    try:
        assert device.info["model"] == "TLSimuMono"
        assert device.fetch(0.2) is None  # nothing without a trigger
        for _ in range(3):
            device.software_trigger()
            frame, _ = device.fetch(2.0)
            assert frame.shape == (120, 160) and frame.dtype == np.uint8 and frame.max() > frame.min()
            assert device.fetch(0.05) is None
    finally:
        device.close()
    with pytest.raises(CameraUnavailable, match="PixelFormat is read-only at Mono8; cannot set Mono16"):
        GenICamDevice.open(CameraSettings((TLSIMU,), serial="SN_InterfaceA_0", pixel_format="Mono16",
                                          trigger_mode="software"))


def test_buffer_to_array_copies_and_checks_the_size():
    data = np.arange(12, dtype=np.uint8)
    image = buffer_to_array(data, 4, 3, "Mono8")
    data[0] = 99
    assert image.shape == (3, 4) and image[0, 0] == 0  # a copy: the producer reuses its buffer
    wide = buffer_to_array(np.array([1, 0, 0, 1], np.uint8), 2, 1, "Mono12")  # little-endian 16-bit words
    assert wide.dtype == np.uint16 and wide.tolist() == [[1, 256]]
    with pytest.raises(CameraUnavailable, match="has 11 pixels; expected 12"):
        buffer_to_array(np.zeros(11, np.uint8), 4, 3, "Mono8")


def _trigger(index):
    return Trigger(sequence_id=5, pattern_index=index, pattern_count=4)


def test_hardware_pairing_is_first_in_first_out_whichever_side_arrives_first():
    pairer = FramePairer("hardware", window_s=0.5)
    assert pairer.add_frame("f0", 0.00) == ([], False)       # frame before its Trigger: held
    assert pairer.add_trigger(_trigger(0), 0.01) == [("f0", _trigger(0))]
    assert pairer.add_trigger(_trigger(1), 0.02) == []       # Trigger before its frame: waits
    assert pairer.add_frame("f1", 0.03) == ([("f1", _trigger(1))], False)
    pairer.add_trigger(_trigger(2), 0.04)
    pairer.add_frame("stray", 0.05)                          # paired with Trigger 2 (FIFO)
    pairer.add_frame("late", 0.10)
    assert pairer.expire(0.55) == ([], 0) and pairer.expire(0.61) == ([], 1)  # 'late' dropped after 0.5 s
    pairer.add_trigger(_trigger(3), 1.0)
    assert pairer.expire(1.6) == ([_trigger(3)], 0) and pairer.unpaired_frames == 1


def test_free_running_pairs_each_trigger_with_the_next_frame_only():
    pairer = FramePairer("free-running", window_s=0.2)
    assert pairer.add_frame("before", 0.0) == ([], True)     # nobody waiting: unpaired
    pairer.add_trigger(_trigger(0), 0.01)
    pairer.add_trigger(_trigger(1), 0.02)
    assert pairer.add_frame("a", 0.015) == ([("a", _trigger(0))], False)
    assert pairer.add_frame("b", 0.016) == ([], True)        # arrived before Trigger 1 was received
    assert pairer.add_frame("c", 0.03) == ([("c", _trigger(1))], False)
    pairer.add_trigger(_trigger(2), 0.1)
    assert pairer.expire(0.31) == ([_trigger(2)], 0) and pairer.unpaired_frames == 2


@pytest.mark.parametrize("mode", ["hardware", "free-running"])
def test_the_claimant_named_before_a_frame_is_copied_is_the_trigger_it_pairs_with(mode):
    """The node copies a frame straight into its burst's row: it asks ``claimant`` before the copy, ``add_frame``
    pairs after it; over 400 random arrivals of Triggers and frames (either first) the two agree every time."""
    rng = np.random.default_rng(7)
    pairer = FramePairer(mode, window_s=0.05)
    now, index, frames, claimed = 0.0, 0, 0, 0
    for _ in range(400):
        now += float(rng.uniform(0.0, 0.02))
        if rng.random() < 0.5:
            pairer.add_trigger(_trigger(index), now)
            index += 1
            continue
        claimant = pairer.claimant(now)
        pairs, _ = pairer.add_frame("frame", now)
        assert (pairs[0][1] if pairs else None) == claimant
        frames += 1
        claimed += claimant is not None
        pairer.expire(now)
    assert claimed > 50 and frames - claimed > 10  # both met: frames that pair at once and frames that do not
