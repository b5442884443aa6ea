"""The phase node given ``frame_bursts:=true``: an entry's frames in one FringeBurst give the PhaseMaps of the same
frames one by one, bit for bit; a short burst fails its scan, naming the missing pattern (issue 20)."""
from __future__ import annotations

import numpy as np
import pytest

from dptpu.messages import FringeBurst, FringeFrame, Image, PhaseMaps, ScanStatus
from dptpu.nodes.harness import NodeHarness, fringe_frames
from dptpu.nodes.phase import PhaseNode
from tests.nodes.test_cloud_scene import plane_scene


@pytest.fixture(scope="module")
def scene():
    return plane_scene()


def bursts_of(frames: list[FringeFrame], *, skip=()) -> list[FringeBurst]:
    """The frames of each entry (a run of one frequency) as one burst, as the sim and camera nodes make them;
    ``skip``: pattern indices left out (lost frames)."""
    entries: dict[float, list[FringeFrame]] = {}
    for frame in frames:
        if frame.trigger.pattern_index not in skip:
            entries.setdefault(frame.trigger.frequency, []).append(frame)
    return [FringeBurst.from_frames(np.stack([f.image.to_array() for f in entry]), [f.trigger for f in entry],
                                    header=entry[-1].image.header) for entry in entries.values()]


def run_scans(scans, *, bursts: bool, count_status: int):
    """PhaseMaps, textures and statuses of the phase node fed ``scans`` (lists of FringeFrames)."""
    with NodeHarness() as harness:
        harness.start(PhaseNode, timeout_s=0.4, frame_bursts=bursts)
        camera = (harness.publisher(FringeBurst, "/camera/frame_bursts") if bursts
                  else harness.publisher(FringeFrame, "/camera/image_raw"))
        phase = harness.collect(PhaseMaps, "/scanner/phase")
        texture = harness.collect(Image, "/scanner/texture")
        status = harness.collect(ScanStatus, "/scanner/status")
        harness.connect()
        published = 0
        for frames, skip in scans:
            for msg in (bursts_of(frames, skip=skip) if bursts else [f for f in frames
                                                                      if f.trigger.pattern_index not in skip]):
                camera.publish(msg)
            published += not skip
            if published:
                harness.wait(phase, published)
        harness.wait(status, count_status)
        return list(phase.messages), list(texture.messages), list(status.messages)


@pytest.mark.parametrize("steps, dtype", [((4, 4), np.uint8), ((12, 3), np.uint16)])
def test_bursts_give_the_phase_maps_of_single_frames_bit_for_bit(scene, steps, dtype):
    frequencies = (16.0, 1.0)
    scale = 1 if dtype == np.uint8 else 16  # mono16: 12-bit digital numbers
    stacks = [scene.frames(f, steps=n, seed=k).astype(dtype) * scale for k, (f, n) in enumerate(zip(frequencies,
                                                                                                     steps))]
    scans = [(fringe_frames(stacks, frequencies, sequence_id=s), ()) for s in (3, 4)]
    single = run_scans(scans, bursts=False, count_status=2)
    burst = run_scans(scans, bursts=True, count_status=2)
    for a, b in zip(single[0], burst[0]):
        assert (a.sequence_id, a.header.stamp, a.steps.tolist()) == (b.sequence_id, b.header.stamp, list(steps))
        for name in ("phases", "modulation", "valid"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
        assert np.count_nonzero(a.valid) > 0.9 * a.valid.size
    for a, b in zip(single[1], burst[1]):
        np.testing.assert_array_equal(a.to_array(), b.to_array())
    assert [s.state for s in burst[2]] == ["processing", "processing"]


def test_a_short_burst_fails_its_scan_naming_the_missing_pattern_and_the_next_scan_is_whole(scene):
    frequencies = (16.0, 1.0)
    stacks = [scene.frames(f, steps=4, seed=k) for k, f in enumerate(frequencies)]
    scans = [(fringe_frames(stacks, frequencies, sequence_id=8), {6}),
             (fringe_frames(stacks, frequencies, sequence_id=9), ())]
    maps, _, statuses = run_scans(scans, bursts=True, count_status=2)
    assert [m.sequence_id for m in maps] == [9]
    failed = next(s for s in statuses if s.sequence_id == 8)
    assert failed.state == "failed" and "received 7 of 8 frames; missing pattern 6" in failed.reason, failed.reason
