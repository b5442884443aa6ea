"""The camera node with ``frame_bursts:=true``, a real process on the shipped viky.cti producer (issue 20).

The probe plays the projector of a 2 x 3-step sequence and a white reference (7 patterns); the camera answers with
one FringeBurst per entry. viky draws a 20x20 black square on white that moves one pixel along x and y each frame, so
every frame is told apart by where its square is. Shared memory is on from 1 kB, so the bursts' buffers are loaned
segments and each frame's copy out of the producer's buffer goes straight into its row of its burst (the node says
at shutdown how many frames were copied twice).
"""
from __future__ import annotations

import time

import numpy as np
import pytest

from dptpu.graph import Parameter
from dptpu.graph.parameter_client import AsyncParameterClient
from dptpu.messages import FringeBurst, FringeFrame, Trigger
from tests.graph.nodes.shm_peer import is_shared
from tests.nodes.camera.test_camera_node import FAST, NODE, SMALL, TLSIMU, publish_spaced

BURSTS = ["-p", "trigger_mode:=free-running", "-p", "frame_rate_hz:=100.0", "-p", "frame_bursts:=true", *SMALL, *FAST]
SHM = {"DPTPU_SHM_MIN_BYTES": "1024"}


def scan(sequence_id: int, *, white: bool = True) -> list[Trigger]:
    """Triggers of 2 x 3 steps (8 and 1 periods), then a white reference when ``white``."""
    count = 7 if white else 6
    sent = [Trigger(sequence_id=sequence_id, pattern_index=3 * entry + step, pattern_count=count, frequency=frequency,
                    steps=3, step=step) for entry, frequency in enumerate((8.0, 1.0)) for step in range(3)]
    if white:
        sent.append(Trigger(sequence_id=sequence_id, pattern_index=6, pattern_count=7, steps=1, kind="white"))
    return sent


def square_corner(frame: np.ndarray) -> tuple[int, int]:
    """(row, column) of viky's one 20x20 black square's top left corner; AssertionError if the frame is not one."""
    rows, cols = np.nonzero(frame == 0)
    assert rows.size == 400 and np.ptp(rows) == np.ptp(cols) == 19
    assert np.count_nonzero(frame == 255) == frame.size - 400  # white elsewhere
    return int(rows.min()), int(cols.min())


def start(spawn_node, probe, *subscribed):
    """The camera with ``frame_bursts:=true``, connected to the probe's inboxes (topic, type) and its Triggers (and,
    with an inbox of ``/camera/image_raw``, given the time to note that subscriber)."""
    inboxes = [probe.subscribe(msg_type, topic) for topic, msg_type in subscribed]
    trigger_pub = probe.publisher(Trigger, "/projector/trigger")
    node = spawn_node(NODE, "--ros-args", *BURSTS, env=SHM)
    assert node.wait_for_stderr("trigger mode free-running", timeout=20)
    assert trigger_pub.wait_for_subscriptions(1, timeout_sec=10)
    for inbox in inboxes:
        inbox.wait_for_publishers(1)
    if ("/camera/image_raw", FringeFrame) in subscribed:
        time.sleep(1.0)  # the node's timer notes image_raw's subscribers every 0.1 s (given ten times that under load)
    return node, trigger_pub, inboxes


def test_each_entry_is_one_burst_of_the_frames_published_alone_copied_once_into_a_loaned_segment(spawn_node, probe):
    node, trigger_pub, (bursts, frames) = start(spawn_node, probe, ("/camera/frame_bursts", FringeBurst),
                                                ("/camera/image_raw", FringeFrame))
    sent = scan(5)
    publish_spaced(trigger_pub, sent)
    received = bursts.wait(3, timeout=10)
    singles = {f.trigger.pattern_index: f for f in frames.wait(7, timeout=10)}  # image_raw has a subscriber
    assert [[t.pattern_index for t in b.triggers] for b in received] == [[0, 1, 2], [3, 4, 5], [6]]
    assert [t for b in received for t in b.triggers] == sent
    corners = []
    for burst in received:
        stack = burst.frames()
        assert stack.shape == (len(burst.triggers), 120, 160) and burst.image.encoding == "mono8"
        assert is_shared(stack)  # through shared memory (a loaned segment, published without a further copy)
        assert burst.image.header.frame_id == "scanner_optical_frame"
        for trigger, frame in zip(burst.triggers, stack):
            single = singles[trigger.pattern_index]
            np.testing.assert_array_equal(frame, single.image.to_array())  # the very frame published alone
            assert burst.image.header.stamp.to_ns() >= single.image.header.stamp.to_ns()  # the last frame's
            corners.append(square_corner(frame))
    assert len(set(corners)) == 7  # seven frames of the producer, none repeated
    node.terminate()
    assert node.wait(timeout=15) == 0
    assert "camera: published 3 bursts and 7 single frames; 0 frame(s) copied twice" in node.stderr


def test_a_lost_trigger_gives_a_short_burst_and_the_later_entries_still_come_and_the_parameter_is_read_only(
        spawn_node, probe):
    node, trigger_pub, (bursts,) = start(spawn_node, probe, ("/camera/frame_bursts", FringeBurst))
    first, second = scan(6), scan(7, white=False)
    del first[1]  # entry 0 short: sent as the next entry's first frame comes
    del second[5]  # the scan's last frame: sent by the timer once it is max_wait_s late
    publish_spaced(trigger_pub, first + second)
    received = bursts.wait(5, timeout=10)
    assert [(b.triggers[0].sequence_id, [t.pattern_index for t in b.triggers]) for b in received] == [
        (6, [0, 2]), (6, [3, 4, 5]), (6, [6]), (7, [0, 1, 2]), (7, [3, 4])]
    corners = [square_corner(frame) for burst in received for frame in burst.frames()]
    assert len(set(corners)) == 11
    assert all(is_shared(b.frames()) for b in received)  # short bursts too (copied into a segment of their size)

    client = AsyncParameterClient(probe.node, "/camera")
    assert client.wait_for_services(timeout_sec=20)
    future = client.set_parameters([Parameter("frame_bursts", value=False)])
    assert future.wait(timeout_sec=20)
    refused = future.result().results[0]
    assert (refused.successful, refused.reason) == (False, "Trying to set a read-only parameter: frame_bursts")
    node.terminate()
    assert node.wait(timeout=15) == 0
    # no single frames without an image_raw subscriber; entry 3 of scan 6, foreseen for the short burst's free row,
    # was copied again into its own burst
    assert "camera: published 5 bursts and 0 single frames; 1 frame(s) copied twice" in node.stderr


@pytest.mark.skipif(TLSIMU is None, reason="TLSimu.cti needs the genicam2 wheel (pip install genicam2)")
def test_software_triggered_frames_are_copied_once_into_their_bursts(spawn_node, probe):
    bursts = probe.subscribe(FringeBurst, "/camera/frame_bursts")
    trigger_pub = probe.publisher(Trigger, "/projector/trigger")
    node = spawn_node(NODE, "--ros-args", "-p", f"cti:={TLSIMU}", "-p", "serial:=SN_InterfaceA_0", "-p",
                      "trigger_mode:=software", "-p", "frame_bursts:=true", *SMALL, *FAST, env=SHM)
    assert node.wait_for_stderr("trigger mode software", timeout=20)
    assert trigger_pub.wait_for_subscriptions(1, timeout_sec=10)
    bursts.wait_for_publishers(1)
    sent = scan(8)
    publish_spaced(trigger_pub, sent, gap_s=0.01)
    received = bursts.wait(3, timeout=10)
    assert [t for b in received for t in b.triggers] == sent
    assert [b.frames().shape for b in received] == [(3, 120, 160), (3, 120, 160), (1, 120, 160)]
    assert all(is_shared(b.frames()) for b in received)
    node.terminate()
    assert node.wait(timeout=15) == 0
    assert "camera: published 3 bursts and 0 single frames; 0 frame(s) copied twice" in node.stderr
