"""The sim node in the in-process harness: Trigger in, the twin's frame of that pattern out, ground truth per scan."""
from __future__ import annotations

import logging
import shutil

import numpy as np
import pytest

from dptpu.fpp.phase import wrapped_phase
from dptpu.graph import Parameter
from dptpu.messages import (
    AbsolutePhase,
    CameraInfo,
    FringeBurst,
    FringeFrame,
    Header,
    Image,
    ScanStatus,
    Time,
    Trigger,
    TriggerBurst,
)
from dptpu.nodes.harness import NodeHarness
from dptpu.nodes.plumbing import LATCHED_QOS
from dptpu.nodes.sim import SimNode
from dptpu.nodes.sim.node import parse_drop_frames
from dptpu.nodes.sim.source import SimScene, capture_scenes, load_source
from tests.graph.nodes.shm_peer import is_shared
from tests.nodes.test_frame_bursts_outside import _Records

SEQUENCE = "16x4,1x4"
PARAMS = dict(source="raycast", size="64x48", scenes="plane,sphere", sequence=SEQUENCE)


def _triggers(sequence_id: int, entries=((16.0, 4), (1.0, 4)), stamp_ns: int = 1_700_000_000_000_000_000):
    count = sum(n for _, n in entries)
    out, index = [], 0
    for frequency, steps in entries:
        for step in range(steps):
            header = Header(stamp=Time.from_ns(stamp_ns + index * 1_333_333), frame_id="projector")
            out.append(Trigger(header=header, sequence_id=sequence_id, pattern_index=index, pattern_count=count,
                               frequency=frequency, steps=steps, step=step))
            index += 1
    return out


def _run(harness, node_params, triggers, *, frames_expected):
    harness.start(SimNode, **node_params)
    trigger_pub = harness.publisher(Trigger, "/projector/trigger", 100)
    frames = harness.collect(FringeFrame, "/camera/image_raw")
    truth = harness.collect(AbsolutePhase, "/sim/ground_truth")
    truth_depth = harness.collect(Image, "/sim/ground_truth_depth")
    status = harness.collect(ScanStatus, "/scanner/status")
    harness.connect(timeout_s=30.0)
    for trigger in triggers:
        trigger_pub.publish(trigger)
    harness.wait(frames, frames_expected)
    harness.spin_for(0.3)
    return frames, truth, truth_depth, status


def test_each_trigger_gets_the_frame_of_its_frequency_and_step_with_the_scans_ground_truth():
    with NodeHarness() as harness:
        frames, truth, truth_depth, status = _run(harness, PARAMS, _triggers(1), frames_expected=8)
        info = harness.collect(CameraInfo, "/camera/camera_info", LATCHED_QOS)
        harness.wait(info, 1)
    source = load_source("raycast", rig="nominal", size="64x48", scenes="plane,sphere", sequence=SEQUENCE)
    plane = source.scenes[0]
    got = sorted(frames.messages, key=lambda m: m.trigger.pattern_index)
    assert [m.trigger.pattern_index for m in got] == list(range(8))
    for message in got:
        expected = plane.stack(message.trigger.frequency, message.trigger.steps)[message.trigger.step]
        np.testing.assert_array_equal(message.image.to_array(), expected)  # same render, same seed
        assert message.image.header.stamp == message.trigger.header.stamp
        assert message.image.header.frame_id == "scanner_optical_frame"
    (gt,) = truth.messages
    assert (gt.sequence_id, gt.frequency, gt.method) == (1, 16.0, "ground_truth:plane")
    # the frames decode to the true phase: wrapped phase of f = 16 against Psi_true mod 2 pi (Eq. 2, Eq. 3)
    stack = np.stack([m.image.to_array() for m in got[:4]])
    maps = wrapped_phase(stack)
    error = np.angle(np.exp(1j * (maps.phase - gt.absolute_phase)))[gt.valid]
    assert gt.valid.mean() > 0.9 and np.sqrt(np.mean(error**2)) < 0.05
    np.testing.assert_array_equal(gt.fringe_order[gt.valid], np.floor(gt.absolute_phase[gt.valid] / (2 * np.pi)))
    (depth,) = truth_depth.messages
    assert depth.header.stamp == gt.header.stamp and depth.encoding == "32FC1"
    assert np.nanmedian(depth.to_array()) == pytest.approx(0.8, abs=0.01)  # the plane at the working distance, m
    assert info.messages[0].width == 64 and info.messages[0].k[0] == pytest.approx(2600 * 64 / 640)
    assert not status.messages


def test_scenes_change_scan_by_scan_and_unknown_patterns_are_reported_without_stopping():
    triggers = _triggers(2) + _triggers(3, entries=((32.0, 4),))[:1] + _triggers(3)[4:]
    with NodeHarness() as harness:
        frames, truth, _, status = _run(harness, PARAMS, triggers, frames_expected=12)
        node = harness.nodes[0]
        harness.spin_until(lambda: len(status) >= 1, 5.0)
    assert [m.method for m in truth.messages] == ["ground_truth:sphere", "ground_truth:plane"]  # scan 2, scan 3
    (failed,) = status.messages
    assert (failed.sequence_id, failed.level, failed.state) == (3, ScanStatus.ERROR, "failed")
    assert "sim: no frame for pattern 0 of scan 3 (f=32, step 0 of 4); scene plane has 16x4, 1x4" == failed.reason
    assert node.triggers_unknown == 1 and node.frames_published == 12


def test_dropped_frames_are_left_out():
    with NodeHarness() as harness:
        frames, _, _, _ = _run(harness, dict(PARAMS, drop_frames="1/5,1/2", frame_rate_hz=200.0), _triggers(1),
                               frames_expected=6)
        harness.spin_for(0.3)
    assert sorted(m.trigger.pattern_index for m in frames.messages) == [0, 1, 3, 4, 6, 7]


def test_capture_folders_are_replayed_with_their_ground_truth(tmp_path):
    from dptpu.sim.image_formation import SequenceSpec
    from dptpu.sim.render import render_capture
    from dptpu.sim.rig import load_twin_rig
    from dptpu.sim.scenes import load_scene

    rig = load_twin_rig("nominal", size="64x48")
    for name in ("plane", "board"):
        render_capture(rig, load_scene(name, rig), [SequenceSpec(16, 4), SequenceSpec(1, 4)], tmp_path / name)
    scenes, loaded_rig, axis, sign = capture_scenes(tmp_path)
    assert [s.name for s in scenes] == ["board", "plane"] and (axis, sign) == ("x", -1)
    assert loaded_rig.camera.size == (64, 48)
    assert sorted(scenes[1].frames) == [(1.0, 4), (16.0, 4)] and scenes[1].stack(16.0, 4).shape == (4, 48, 64)
    assert np.nanmedian(scenes[1].depth_m) == pytest.approx(0.8, abs=0.01)
    with NodeHarness() as harness:
        frames, truth, _, _ = _run(harness, dict(source=str(tmp_path)), _triggers(1), frames_expected=8)
    assert truth.messages[0].method == "ground_truth:board"


def test_a_capture_without_ground_truth_a_real_rigs_scan_is_replayed_without_truth(tmp_path):
    from dptpu.sim.image_formation import SequenceSpec
    from dptpu.sim.render import render_capture
    from dptpu.sim.rig import load_twin_rig
    from dptpu.sim.scenes import load_scene

    rig = load_twin_rig("nominal", size="64x48")
    folder = tmp_path / "saved"
    render_capture(rig, load_scene("plane", rig), [SequenceSpec(16, 4), SequenceSpec(1, 4)], folder)
    (folder / "gt.npz").unlink()  # as ~/capture_and_save writes a real rig's scan: frames and calibration only
    text = (folder / "capture.yaml").read_text()
    (folder / "capture.yaml").write_text(text.replace("ground_truth: gt.npz\n", ""))
    (scene,), _, _, _ = capture_scenes(folder)
    assert not scene.has_truth and not scene.valid.any() and np.isnan(scene.depth_m).all()
    assert scene.stack(16.0, 4).shape == (4, 48, 64)
    records = _Records()
    logging.getLogger("dptpu.node").addHandler(records)
    try:
        with NodeHarness() as harness:
            frames, truth, truth_depth, _ = _run(harness, dict(source=str(folder)), _triggers(1) + _triggers(2),
                                                 frames_expected=16)
    finally:
        logging.getLogger("dptpu.node").removeHandler(records)
    got = sorted(frames.messages, key=lambda m: (m.trigger.sequence_id, m.trigger.pattern_index))
    for message in got:  # the saved frames, bit for bit
        expected = scene.stack(message.trigger.frequency, message.trigger.steps)[message.trigger.step]
        np.testing.assert_array_equal(message.image.to_array(), expected)
    assert not truth.messages and not truth_depth.messages
    assert [m for m in records.messages if "has no ground truth" in m] == [
        "scene saved has no ground truth (its capture has no gt.npz): no /sim/ground_truth for its scans; grade "
        "them with ground_truth:=false"]  # once, not once a scan
    shutil.copytree(folder, tmp_path / "bare")
    (tmp_path / "bare" / "capture.yaml").write_text(text.replace("ground_truth: gt.npz\n", "").replace(
        "calibration: calibration.yaml\n", ""))
    with pytest.raises(ValueError, match="this one lacks calibration"):
        capture_scenes(tmp_path / "bare")


def test_bad_parameters_raise_value_errors_naming_them(tmp_path):
    with pytest.raises(ValueError, match=r"parameter drop_frames: '3:5' must be SEQUENCE_ID/PATTERN_INDEX"):
        parse_drop_frames("3:5")
    with pytest.raises(ValueError, match="no dptpu-capture/1 folder"):
        load_source(str(tmp_path), rig="nominal", size="64x48")
    with pytest.raises(ValueError, match=r"parameter sequence: '16' must be FREQUENCYxSTEPS"):
        load_source("raycast", rig="nominal", size="64x48", sequence="16")
    with pytest.raises(ValueError, match=r"random:SEED"):
        load_source("raycast", rig="nominal", size="64x48", scenes="random:x")


def test_shipped_renders_are_used_only_when_they_hold_the_asked_size_and_sequences(tmp_path, monkeypatch):
    from dptpu.nodes.sim import source as sim_source
    from dptpu.sim.image_formation import SequenceSpec
    from dptpu.sim.render import render_capture
    from dptpu.sim.rig import load_twin_rig
    from dptpu.sim.scenes import load_scene

    rig = load_twin_rig("nominal", size="64x48")
    render_capture(rig, load_scene("plane", rig), [SequenceSpec(16, 4), SequenceSpec(1, 4)], tmp_path / "plane")
    monkeypatch.setattr(sim_source, "shipped_root", lambda: tmp_path)
    shipped = load_source("shipped", rig="nominal", size="64x48", scenes="sphere", sequence="16x4,1x4")
    assert shipped.kind == "shipped" and [s.name for s in shipped.scenes] == ["plane"]
    other = load_source("shipped", rig="nominal", size="32x24", scenes="sphere", sequence="16x4,1x4,8x4")
    assert other.kind == "raycast" and [s.name for s in other.scenes] == ["sphere"]
    assert "lack the size 32x24 (they are 64x48) and the sequence(s) 8x4 (they hold 16x4, 1x4)" in other.note


def test_a_12_step_capture_serves_its_3_step_sequence_as_every_fourth_frame(tmp_path):
    """Eq. (1): image n of N steps is A + B cos(phi - 2 pi n / N); frame 4k of 12 steps is frame k of 3 steps."""
    from dptpu.sim.image_formation import SequenceSpec
    from dptpu.sim.render import render_capture
    from dptpu.sim.rig import load_twin_rig
    from dptpu.sim.scenes import load_scene

    rig = load_twin_rig("nominal", size="64x48")
    render_capture(rig, load_scene("plane", rig), [SequenceSpec(16, 12), SequenceSpec(16, 3)], tmp_path / "twelve")
    (scene,), _, _, _ = capture_scenes(tmp_path)
    three = scene.frames[(16.0, 3)]
    only_twelve = SimScene(name="only-12", frames={(16.0, 12): scene.frames[(16.0, 12)]},
                           projector_coord=scene.projector_coord, valid=scene.valid, depth_m=scene.depth_m)
    served = only_twelve.stack(16.0, 3)
    assert served.shape == (3, 48, 64)
    np.testing.assert_array_equal(served, scene.frames[(16.0, 12)][[0, 4, 8]])
    # the same phase as a 3-step render of the scene (both noiseless 8-bit: within quantization)
    lit = scene.valid
    difference = np.angle(np.exp(1j * (wrapped_phase(served).phase - wrapped_phase(three).phase)))[lit]
    assert np.abs(difference).max() < 0.02
    assert scene.stack(16.0, 5) is None  # 12 is not a multiple of 5


def test_raycast_source_announces_its_rig_before_rendering():
    # the sim node publishes the CameraInfo from this callback, so the cloud node builds its tables while the
    # scenes render (seconds at 640x480), not while the first scans arrive
    seen = []

    def on_rig(rig):
        seen.append((rig.camera.size, rig.camera.K[0, 0]))

    source = load_source("raycast", rig="nominal", size="64x48", scenes="plane", sequence=SEQUENCE, on_rig=on_rig)
    assert seen == [((64, 48), pytest.approx(2600 * 64 / 640))]
    assert source.rig.camera.size == (64, 48)


def test_a_trigger_with_zero_steps_is_refused_with_its_reason_and_the_next_scan_is_served():
    """Trigger.steps = 0 ("unknown" on the wire) once raised ZeroDivisionError in the callback (issue 19)."""
    header = Header(stamp=Time.from_ns(1_700_000_000_000_000_000), frame_id="projector")
    broken = [Trigger(header=header, sequence_id=4, pattern_index=0, pattern_count=8, frequency=16.0, steps=0, step=0),
              Trigger(header=header, sequence_id=4, pattern_index=1, pattern_count=8, frequency=float("nan"), steps=4,
                      step=1)]
    with NodeHarness() as harness:
        frames, _, _, status = _run(harness, PARAMS, broken + _triggers(5), frames_expected=8)
        node = harness.nodes[0]
        harness.spin_until(lambda: len(status) >= 1, 5.0)
    (failed,) = status.messages  # one report for scan 4, the later refusals of the same scan only logged
    assert (failed.sequence_id, failed.level, failed.state) == (4, ScanStatus.ERROR, "failed")
    assert failed.reason == ("sim: no frame for pattern 0 of scan 4 (f=16, step 0 of 0); refused: Trigger.steps is 0 "
                             "(unknown); the sim needs N >= 1 to pick the frame")
    assert node.triggers_unknown == 2 and node.frames_published == 8
    assert {m.trigger.sequence_id for m in frames.messages} == {5}


def test_a_frame_id_set_at_run_time_reaches_the_latched_camera_info_and_the_next_frames():
    """``param set /sim frame_id`` changed the frames but the latched /camera/camera_info kept the old frame, so a
    subscriber that came later (the cloud node restarted, rviz) paired the new frames with the old frame's info."""
    with NodeHarness() as harness:
        node = harness.start(SimNode, **PARAMS)
        trigger_pub = harness.publisher(Trigger, "/projector/trigger", 100)
        frames = harness.collect(FringeFrame, "/camera/image_raw")
        harness.connect(timeout_s=30.0)
        (result,) = node.set_parameters([Parameter("frame_id", value="left_camera_optical_frame")])
        assert result.successful
        (refused,) = node.set_parameters([Parameter("frame_id", value="")])
        assert not refused.successful and node.frame_id == "left_camera_optical_frame"
        late = harness.collect(CameraInfo, "/camera/camera_info", LATCHED_QOS)  # joins after the set
        harness.wait(late, 1)
        for trigger in _triggers(2):
            trigger_pub.publish(trigger)
        harness.wait(frames, 8)
    assert [m.header.frame_id for m in late.messages] == ["left_camera_optical_frame"]
    assert late.messages[0].width == 64  # the same rig's camera, announced again
    assert {m.image.header.frame_id for m in frames.messages} == {"left_camera_optical_frame"}


def test_frames_are_copied_once_into_loaned_segments_and_arrive_bit_for_bit(monkeypatch):
    monkeypatch.setenv("DPTPU_SHM_MIN_BYTES", "1024")  # the 64x48 frames (3 kB) through shared memory
    with NodeHarness() as harness:
        node = harness.start(SimNode, **PARAMS)

        def no_copy(*args, **kwargs):
            raise AssertionError("a loaned frame was copied into a segment a second time")

        node.image_pub._pool.write = no_copy
        trigger_pub = harness.publisher(Trigger, "/projector/trigger", 100)
        frames = harness.collect(FringeFrame, "/camera/image_raw")
        harness.connect(timeout_s=30.0)
        for trigger in _triggers(1):
            trigger_pub.publish(trigger)
        harness.wait(frames, 8)
        plane = node.source.scenes[0]
        for message in frames.messages:
            image = message.image.to_array()
            assert is_shared(image) and not image.flags.writeable
            np.testing.assert_array_equal(image, plane.stack(message.trigger.frequency,
                                                             message.trigger.steps)[message.trigger.step])
        assert node.image_pub.shared_count == 8


def test_a_source_serves_sequences_of_its_steps_and_of_their_divisors():
    """12-step renders serve a 3-step scan (frames 0, 4, 8): the sim said "the projector's sequence has 64x3, 1x3,
    which the source lacks ... those Triggers get no frame" and then served every one of them."""
    source = load_source("raycast", rig="nominal", size="64x48", scenes="plane", sequence="16x12,1x12")
    assert source.serves(16.0, 12) and source.serves(16.0, 3) and source.serves(1.0, 4) and source.serves(1.0, 6)
    assert not source.serves(16.0, 5) and not source.serves(16.0, 24) and not source.serves(8.0, 3)
    served = source.scenes[0].stack(16.0, 3)
    assert served is not None and np.array_equal(served, source.scenes[0].stack(16.0, 12)[::4])


def _run_bursts(harness, node_params, triggers, *, bursts_expected, frames_too: bool = False):
    node = harness.start(SimNode, **node_params, frame_bursts=True)
    trigger_pub = harness.publisher(Trigger, "/projector/trigger", 100)
    bursts = harness.collect(FringeBurst, "/camera/frame_bursts")
    frames = harness.collect(FringeFrame, "/camera/image_raw") if frames_too else None
    harness.connect(timeout_s=30.0)
    for trigger in triggers:
        trigger_pub.publish(trigger)
    harness.wait(bursts, bursts_expected)
    harness.spin_for(0.3)
    return node, bursts, frames


def test_with_frame_bursts_each_entry_is_one_loaned_burst_of_the_frames_single_triggers_get(monkeypatch):
    monkeypatch.setenv("DPTPU_SHM_MIN_BYTES", "1024")  # the 64x48 bursts (12 kB) through shared memory
    with NodeHarness() as harness:
        node, bursts, frames = _run_bursts(harness, PARAMS, _triggers(1) + _triggers(2), bursts_expected=4)
        plane, sphere = node.source.scenes
        assert node.burst_pub.shared_count == 4 and node.bursts_published == 4
        assert node.frames_published == 16 and node.image_pub.get_subscription_count() == 0
        got = bursts.messages
        assert [[t.pattern_index for t in b.triggers] for b in got] == [[0, 1, 2, 3], [4, 5, 6, 7]] * 2
        for burst, scene in zip(got, (plane, plane, sphere, sphere)):
            frequency, steps = burst.triggers[0].frequency, burst.triggers[0].steps
            stacked = burst.frames()
            assert is_shared(stacked) and not stacked.flags.writeable
            np.testing.assert_array_equal(stacked, scene.stack(frequency, steps))  # the frames, in step order
            assert burst.image.header.stamp == burst.triggers[-1].header.stamp  # the last frame's exposure
            assert burst.image.header.frame_id == "scanner_optical_frame"


def test_with_frame_bursts_a_dropped_frame_shortens_its_burst_and_single_frames_go_to_a_listener():
    with NodeHarness() as harness:
        node, bursts, frames = _run_bursts(harness, dict(PARAMS, drop_frames="1/2,1/7"), _triggers(1),
                                           bursts_expected=2, frames_too=True)
        harness.wait(frames, 6)
    assert [[t.pattern_index for t in b.triggers] for b in bursts.messages] == [[0, 1, 3], [4, 5, 6]]
    assert sorted(m.trigger.pattern_index for m in frames.messages) == [0, 1, 3, 4, 5, 6]
    plane = node.source.scenes[0]
    np.testing.assert_array_equal(bursts.messages[1].frames(), plane.stack(1.0, 4)[:3])
    assert node.frames_dropped == 2


def test_with_trigger_bursts_an_entrys_triggers_in_one_message_get_its_frames_as_one_burst():
    triggers = _triggers(1) + _triggers(2)
    with NodeHarness() as harness:
        node = harness.start(SimNode, **PARAMS, frame_bursts=True, trigger_bursts=True)
        trigger_pub = harness.publisher(TriggerBurst, "/projector/trigger_bursts", 20)
        bursts = harness.collect(FringeBurst, "/camera/frame_bursts")
        harness.connect(timeout_s=30.0)
        for start in range(0, 16, 4):
            entry = triggers[start:start + 4]
            trigger_pub.publish(TriggerBurst(header=entry[-1].header, triggers=entry))
        harness.wait(bursts, 4)
        harness.spin_for(0.3)
    plane, sphere = node.source.scenes
    assert [[t.pattern_index for t in b.triggers] for b in bursts.messages] == [[0, 1, 2, 3], [4, 5, 6, 7]] * 2
    for burst, scene in zip(bursts.messages, (plane, plane, sphere, sphere)):
        first = burst.triggers[0]
        np.testing.assert_array_equal(burst.frames(), scene.stack(first.frequency, first.steps))
    assert node.frames_published == 16 and node.bursts_published == 4
    assert node.trigger_sub.topic_name == "/projector/trigger_bursts"  # the single Triggers' topic is not taken


def test_with_trigger_bursts_a_projector_sending_single_triggers_only_is_named_once():
    records = _Records()
    logging.getLogger("dptpu.node").addHandler(records)
    try:
        with NodeHarness() as harness:
            node = harness.start(SimNode, **PARAMS, frame_bursts=True, trigger_bursts=True)
            harness.collect(FringeBurst, "/camera/frame_bursts")  # the phase node: the sim takes Triggers
            harness.publisher(Trigger, "/projector/trigger", 100, connect=False)  # a projector, trigger_bursts false
            harness.connect(timeout_s=30.0)
            assert harness.spin_until(lambda: any("no Trigger can come" in m for m in records.messages), 10.0), \
                records.messages
            harness.spin_for(2.5)  # said once
    finally:
        logging.getLogger("dptpu.node").removeHandler(records)
    warnings = [m for m in records.messages if "no Trigger can come" in m]
    assert warnings == ["no Trigger can come: nothing publishes /projector/trigger_bursts, where this node takes "
                        "TriggerBursts (trigger_bursts:=true), while /harness_probe publish(es) single Triggers on "
                        "/projector/trigger; give this node trigger_bursts:=false, or the projector "
                        "trigger_bursts:=true"]
    assert node.triggers_received == 0
