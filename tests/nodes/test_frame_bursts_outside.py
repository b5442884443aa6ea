"""Frame bursts used as they were not built for (issue 20, 20X): a slow camera, and a camera side and a phase node
that disagree on ``frame_bursts``."""
from __future__ import annotations

import dataclasses
import logging

import numpy as np

from dptpu.messages import FringeBurst, FringeFrame, Header, Image, PhaseMaps, ScanStatus, Time, Trigger
from dptpu.nodes.frame_bursts import FrameBursts
from dptpu.nodes.harness import NodeHarness, fringe_frames
from dptpu.nodes.phase import PhaseNode
from dptpu.nodes.phase.frame_topic_check import FrameTopicCheck
from dptpu.nodes.sim import SimNode
from tests.nodes.test_cloud_scene import plane_scene
from tests.nodes.test_frame_bursts import frame_of, triggers_of


def _slow_camera(frame_period_s: float, scans: int, *, skip=()):
    """Bursts of ``scans`` 2 x 12-step scans from a camera delivering a frame every ``frame_period_s``, with the
    node's timer calling ``due`` every 0.1 s between frames (as the sim's and camera's do); ``skip``: lost
    (sequence_id, pattern_index). Returns the bursts' pattern indices and the frames allocated."""
    allocated = []
    bursts = FrameBursts(lambda shape, dtype: (allocated.append(shape[0]), np.empty(shape, dtype))[1], max_wait_s=0.5)
    ready, now_s = [], 0.0
    for sequence_id in range(1, scans + 1):
        for trigger in triggers_of(sequence_id, [(64.0, 12), (63.0, 12)]):
            if (sequence_id, trigger.pattern_index) not in skip:
                ready += bursts.add(trigger, frame_of(trigger), int(now_s * 1e9), now_s)
            for tick in np.arange(0.1, frame_period_s, 0.1):
                ready += bursts.due(now_s + tick)
            now_s += frame_period_s
    for tick in np.arange(0.1, 3.0, 0.1):  # the timer after the last frame
        ready += bursts.due(now_s + tick)
    return [[t.pattern_index for t in burst.triggers] for burst in ready], allocated, bursts


def test_a_camera_slower_than_the_wait_still_sends_each_entry_as_one_burst():
    # 0.75 s a frame (1.3 frames/s: a long exposure, or the sim's frame_rate_hz:=1.3): with a fixed 0.5 s wait every
    # frame went alone, 24 bursts a scan each in a buffer of 12 frames (288 frames allocated for 24)
    indices, allocated, bursts = _slow_camera(0.75, 2)
    first, second = list(range(12)), list(range(12, 24))
    # the first frame goes alone (no spacing seen yet), then the wait is twice the spacing seen: 1.5 s
    assert indices == [[0], first[1:], second, first, second]
    assert bursts.frame_spacing_s == 0.75 and bursts.wait_s == 1.5
    assert sum(allocated) == 12 * 5


def test_a_slow_cameras_lost_frame_still_sends_its_short_burst_after_twice_the_frame_spacing():
    indices, _, _ = _slow_camera(0.75, 2, skip={(2, 23)})  # scan 2's last frame lost: its burst goes by the timer
    assert indices[-1] == list(range(12, 23))
    indices, _, _ = _slow_camera(0.75, 2, skip={(2, 5)})  # a middle frame lost: the entry goes as one short burst
    assert indices[3] == [0, 1, 2, 3, 4, 6, 7, 8, 9, 10, 11]


def test_a_fast_camera_keeps_the_half_second_wait():
    indices, allocated, bursts = _slow_camera(0.01, 3, skip={(3, 23)})
    assert len(indices) == 6 and indices[-1] == list(range(12, 23)) and sum(allocated) == 72
    assert abs(bursts.frame_spacing_s - 0.01) < 1e-9 and bursts.wait_s == 0.5


def test_frame_topic_check_warns_once_when_only_the_other_topic_is_published():
    check = FrameTopicCheck("/camera/frame_bursts", "/camera/image_raw", frame_bursts=True)
    assert check.check([], ["/sim"]) is None  # once: discovery may not be complete
    warning = check.check([], ["/sim"])
    assert warning is not None
    for part in ("nothing publishes /camera/frame_bursts", "takes FringeBursts (frame_bursts:=true)",
                 "/sim publishes FringeFrames on /camera/image_raw", "give this node frame_bursts:=false",
                 "the camera side (sim, camera node) frame_bursts:=true"):
        assert part in warning, warning
    assert check.check([], ["/sim"]) is None  # said once
    assert check.check(["/sim"], ["/sim"]) is None  # the camera side restarted with bursts: fine again
    assert check.check([], []) is None and check.check([], []) is None  # no camera side at all: an idle graph
    frames = FrameTopicCheck("/rig/image", "/camera/frame_bursts", frame_bursts=False)
    frames.check([], ["/camera", "/sim"])
    warning = frames.check([], ["/sim", "/camera"])
    assert warning is not None and "/camera, /sim publish FringeBursts on /camera/frame_bursts" in warning
    assert "nothing publishes /rig/image" in warning and "frame_bursts:=true, or the camera side" in warning


class _Records(logging.Handler):
    def __init__(self):
        super().__init__(logging.WARNING)
        self.messages: list[str] = []

    def emit(self, record):
        self.messages.append(record.getMessage())


def test_a_phase_node_taking_bursts_from_a_camera_side_sending_frames_says_so_naming_topic_and_parameter():
    records = _Records()
    logging.getLogger("dptpu.node").addHandler(records)
    try:
        with NodeHarness() as harness:
            node = harness.start(PhaseNode, frame_bursts=True)
            camera = harness.publisher(FringeFrame, "/camera/image_raw", connect=False)  # a sim without bursts
            assert harness.spin_until(lambda: any("no frame can come" in m for m in records.messages), 10.0), \
                records.messages
            harness.spin_for(1.3)  # said once
    finally:
        logging.getLogger("dptpu.node").removeHandler(records)
    (warning,) = [m for m in records.messages if "no frame can come" in m]
    assert f"{harness.probe.get_fully_qualified_name()} publishes FringeFrames on /camera/image_raw" in warning
    assert "give this node frame_bursts:=false" in warning and node.frames_received == 0
    assert camera.topic_name == "/camera/image_raw"


def test_a_phase_node_fed_as_it_expects_says_nothing_of_frame_topics():
    records = _Records()
    logging.getLogger("dptpu.node").addHandler(records)
    try:
        with NodeHarness() as harness:
            harness.start(PhaseNode, frame_bursts=False)
            harness.publisher(FringeFrame, "/camera/image_raw")
            harness.connect()
            harness.spin_for(2.2)  # two checks
    finally:
        logging.getLogger("dptpu.node").removeHandler(records)
    assert not [m for m in records.messages if "no frame can come" in m]


def test_a_sim_publishing_bursts_serves_single_frames_to_a_phase_node_that_takes_frames():
    """The sim with ``frame_bursts:=true`` publishes single frames while ``/camera/image_raw`` has subscribers, and
    counts them towards ``min_subscribers``: a phase node (and cloud) left at ``frame_bursts:=false`` under a sim
    given ``frame_bursts:=true`` gets every frame (it waited for a burst subscriber: scans went missing, 20X)."""
    with NodeHarness() as harness:
        harness.start(SimNode, source="raycast", size="64x48", scenes="plane", sequence="16x4,1x4",
                      frame_bursts=True)
        triggers = harness.publisher(Trigger, "/projector/trigger", 100, connect=False)
        frames = harness.collect(FringeFrame, "/camera/image_raw")  # a phase node with frame_bursts:=false
        assert harness.spin_until(lambda: triggers.get_subscription_count() > 0, 5.0), \
            "the sim took no Trigger: it waits for a subscriber of /camera/frame_bursts"
        for index in range(8):
            header = Header(stamp=Time.from_ns(1_700_000_000_000_000_000 + index), frame_id="projector")
            triggers.publish(Trigger(header=header, sequence_id=1, pattern_index=index, pattern_count=8,
                                     frequency=16.0 if index < 4 else 1.0, steps=4, step=index % 4))
        harness.spin_until(lambda: len(frames) == 8, 5.0)
        assert sorted(m.trigger.pattern_index for m in frames.messages) == list(range(8))


def _phase_fed_bursts(bursts):
    """PhaseMaps and statuses of a phase node (``frame_bursts:=true``) fed ``bursts`` in order, and the node."""
    with NodeHarness() as harness:
        node = harness.start(PhaseNode, timeout_s=0.4, frame_bursts=True)
        camera = harness.publisher(FringeBurst, "/camera/frame_bursts")
        phase = harness.collect(PhaseMaps, "/scanner/phase")
        status = harness.collect(ScanStatus, "/scanner/status")
        harness.connect()
        for burst in bursts:
            camera.publish(burst)
        harness.wait(status, sum(1 for b in bursts if b.triggers and b.triggers[-1].pattern_index == 7))
        harness.spin_for(0.2)
        return list(phase.messages), list(status.messages), node


def _scan_frames(sequence_id: int) -> list[FringeFrame]:
    scene = plane_scene()
    return fringe_frames([scene.frames(16.0, steps=4, seed=0), scene.frames(1.0, steps=4, seed=1)], (16.0, 1.0),
                         sequence_id=sequence_id)


def _burst(frames: list[FringeFrame], *, encoding: str | None = None) -> FringeBurst:
    stacked = np.stack([f.image.to_array() for f in frames])  # (N, H, W)
    burst = FringeBurst.from_frames(stacked, [f.trigger for f in frames], header=frames[-1].image.header)
    if encoding is not None:  # the same bytes said to be another one-byte-a-pixel encoding
        burst = dataclasses.replace(burst, image=dataclasses.replace(burst.image, encoding=encoding))
    return burst


def test_a_whole_scan_in_one_burst_and_an_empty_burst_beside_it():
    # one burst holding both entries (a camera side gathering otherwise), an empty burst (refused, counted), then a
    # scan in its two entry bursts: both scans give the same maps
    whole, split = _scan_frames(5), _scan_frames(6)
    empty = FringeBurst(image=Image(encoding="mono8"), triggers=[])
    maps, statuses, node = _phase_fed_bursts([_burst(whole), empty, _burst(split[:4]), _burst(split[4:])])
    assert [m.sequence_id for m in maps] == [5, 6] and [s.state for s in statuses] == ["processing"] * 2
    for name in ("phases", "modulation", "valid"):
        np.testing.assert_array_equal(getattr(maps[0], name), getattr(maps[1], name), err_msg=name)
    assert np.count_nonzero(maps[0].valid) > 0.5 * maps[0].valid.size
    assert maps[0].header.stamp == whole[-1].image.header.stamp  # the burst's stamp: its last frame's
    assert node.frames_rejected == 1 and node.frames_received == 16


def test_a_burst_of_another_encoding_fails_its_scan_naming_the_patterns_and_the_encoding():
    bad, good = _scan_frames(7), _scan_frames(8)
    maps, statuses, _ = _phase_fed_bursts([_burst(bad[:4], encoding="8UC1"), _burst(bad[4:]), _burst(good[:4]),
                                           _burst(good[4:])])
    assert [m.sequence_id for m in maps] == [8]
    failed = next(s for s in statuses if s.sequence_id == 7)
    assert failed.state == "failed"
    assert "burst of patterns 0..3 unreadable: image encoding must be mono8 or mono16; got '8UC1'" in failed.reason
