"""Scan assembly by sequence_id (nodes/phase/sequence_assembler.py): pure logic, a hand-driven clock."""
from __future__ import annotations

import numpy as np
import pytest

from dptpu.nodes.phase.sequence_assembler import (
    AssembledScan,
    DroppedScan,
    FrameInfo,
    RejectedFrame,
    ScanLayout,
    SequenceAssembler,
)

LAYOUT = ((16.0, 4), (1.0, 3))  # (frequency, steps) per entry: 7 patterns


def frames_of(sequence_id, *, layout=LAYOUT, shape=(6, 8), base=0):
    """Frames of one scan in projection order; image of pattern i is filled with ``base + i``."""
    count = sum(steps for _, steps in layout)
    frames, index = [], 0
    for frequency, steps in layout:
        for step in range(steps):
            frames.append(FrameInfo(sequence_id=sequence_id, pattern_index=index, pattern_count=count,
                                    frequency=frequency, steps=steps, step=step,
                                    image=np.full(shape, base + index, dtype=np.uint8), stamp_ns=1000 + index))
            index += 1
    return frames


def feed(assembler, frames, now_s=0.0):
    events = []
    for frame in frames:
        events += assembler.add(frame, now_s)
    return events


def test_complete_scan_is_stacked_per_entry_in_step_order_whatever_the_arrival_order():
    assembler = SequenceAssembler(timeout_s=1.0)
    frames = frames_of(5)
    shuffled = [frames[i] for i in np.random.default_rng(0).permutation(len(frames))]
    events = feed(assembler, shuffled)
    assert len(events) == 1 and isinstance(events[0], AssembledScan)
    scan = events[0]
    assert scan.sequence_id == 5 and scan.layout.frequencies == (16.0, 1.0) and scan.layout.steps == (4, 3)
    assert [s.shape for s in scan.stacks] == [(4, 6, 8), (3, 6, 8)]
    assert scan.stacks[0][:, 0, 0].tolist() == [0, 1, 2, 3] and scan.stacks[1][:, 0, 0].tolist() == [4, 5, 6]
    assert (scan.first_stamp_ns, scan.last_stamp_ns) == (1000, 1006)
    assert assembler.pending_ids == []


def test_frames_of_two_interleaved_scans_are_never_mixed():
    assembler = SequenceAssembler(timeout_s=1.0)
    a, b = frames_of(1, base=0), frames_of(2, base=100)
    interleaved = [frame for pair in zip(a, b) for frame in pair]
    scans = [e for e in feed(assembler, interleaved) if isinstance(e, AssembledScan)]
    assert [s.sequence_id for s in scans] == [1, 2]
    assert np.concatenate([s[:, 0, 0] for s in scans[0].stacks]).tolist() == list(range(7))
    assert np.concatenate([s[:, 0, 0] for s in scans[1].stacks]).tolist() == list(range(100, 107))


def test_incomplete_scan_is_dropped_after_the_timeout_with_the_missing_patterns_and_the_next_is_fine():
    assembler = SequenceAssembler(timeout_s=0.5)
    frames = frames_of(3)
    del frames[5]
    assert feed(assembler, frames, now_s=10.0) == []
    assert assembler.expire(10.4) == []
    (dropped,) = assembler.expire(10.6)
    assert isinstance(dropped, DroppedScan) and dropped.sequence_id == 3
    assert (dropped.frames_expected, dropped.frames_received) == (7, 6)
    assert dropped.reason == "incomplete after 0.5 s: received 6 of 7 frames; missing pattern 5"
    events = feed(assembler, frames_of(4), now_s=10.7)
    assert [type(e) for e in events] == [AssembledScan] and events[0].sequence_id == 4


def test_frame_of_another_size_fails_its_scan_at_once_and_its_late_frames_are_refused():
    assembler = SequenceAssembler(timeout_s=1.0)
    frames = frames_of(8)
    bad = frames[2]
    frames[2] = FrameInfo(**{**bad.__dict__, "image": np.zeros((5, 8), np.uint8)})
    events = feed(assembler, frames[:3])
    assert len(events) == 1 and isinstance(events[0], DroppedScan)
    assert "pattern 2 (f=16, step 2 of 4) is 8x5 uint8; the scan's first frame was 8x6 uint8" in events[0].reason
    late = feed(assembler, frames[3:4])
    assert isinstance(late[0], RejectedFrame) and "already dropped" in late[0].reason
    assert isinstance(feed(assembler, frames_of(9))[0], AssembledScan)


def test_out_of_order_step_and_duplicate_index_fail_the_scan():
    assembler = SequenceAssembler(timeout_s=1.0)
    frames = frames_of(1)
    f = frames[1]
    frames[1] = FrameInfo(**{**f.__dict__, "step": 3})  # step 3 at pattern 1, but step 0 was pattern 0
    (event,) = feed(assembler, frames[:2])
    assert isinstance(event, DroppedScan) and "out of order" in event.reason
    frames = frames_of(2)
    (event,) = feed(assembler, [frames[0], frames[1], frames[1]])
    assert isinstance(event, DroppedScan) and event.reason == "duplicate frame for pattern_index 1"


def test_pattern_sequence_layout_refuses_an_unknown_frequency_and_a_misplaced_step():
    assembler = SequenceAssembler(timeout_s=1.0)
    assembler.set_layout(ScanLayout(frequencies=(16.0, 1.0), steps=(4, 3), phase_offsets=(0.0, 0.5)))
    frames = frames_of(1, layout=((16.0, 4), (2.0, 3)))
    event, *late = feed(assembler, frames)
    assert isinstance(event, DroppedScan)
    assert "unknown frequency 2 for pattern 4; the PatternSequence has 1 there (frequencies 16, 1)" in event.reason
    assert [type(e) for e in late] == [RejectedFrame, RejectedFrame]  # patterns 5 and 6 of the failed scan
    frames = frames_of(2, layout=((16.0, 3), (1.0, 4)))  # the triggers' own layout differs from the sequence's
    event, *late = feed(assembler, frames[:4])
    assert isinstance(event, DroppedScan) and len(late) == 3
    assert "(f=16, step 0 of 3) is out of order: pattern 0 is step 0 of 4 at f=16" in event.reason
    scans = feed(assembler, frames_of(3))
    assert isinstance(scans[0], AssembledScan) and scans[0].layout.phase_offsets == (0.0, 0.5)


def test_without_pattern_sequence_a_trigger_must_give_pattern_count():
    assembler = SequenceAssembler(timeout_s=1.0)
    frame = FrameInfo(sequence_id=1, pattern_index=0, pattern_count=0, frequency=16.0, steps=4, step=0,
                      image=np.zeros((4, 4), np.uint8))
    (event,) = assembler.add(frame, 0.0)
    assert isinstance(event, DroppedScan) and "pattern_count 0 and no PatternSequence" in event.reason


def test_too_many_pending_scans_supersede_the_oldest():
    assembler = SequenceAssembler(timeout_s=5.0, max_pending_scans=2)
    events = []
    for sequence_id in (1, 2, 3):
        events += assembler.add(frames_of(sequence_id)[0], float(sequence_id))
    (event,) = events
    assert isinstance(event, DroppedScan) and event.sequence_id == 1 and event.reason.startswith("superseded")
    assert assembler.pending_ids == [2, 3]


def test_a_finished_scan_refuses_late_frames_until_its_id_is_forgotten():
    assembler = SequenceAssembler(timeout_s=0.5)
    frames = frames_of(7)
    assert isinstance(feed(assembler, frames, now_s=1.0)[0], AssembledScan)
    (late,) = assembler.add(frames[0], 1.2)
    assert isinstance(late, RejectedFrame) and "already completed" in late.reason
    assert isinstance(feed(assembler, frames, now_s=2.0)[-1], AssembledScan)  # a restarted projector reuses id 7


def test_layout_and_assembler_check_their_arguments():
    with pytest.raises(ValueError, match="steps must be >= 3"):
        ScanLayout(frequencies=(16.0,), steps=(2,))
    with pytest.raises(ValueError, match="one steps and one phase_offset per frequency"):
        ScanLayout(frequencies=(16.0, 1.0), steps=(4,))
    with pytest.raises(ValueError, match="timeout_s must be a number of seconds > 0"):
        SequenceAssembler(timeout_s=0)
    assert ScanLayout(frequencies=(16.0, 1.0), steps=(4, 3)).locate(5) == (1, 1)


def test_finished_ids_are_forgotten_in_order_once_timed_out():
    # the ids of completed and dropped scans are kept timeout_s in the order they finished, and forgotten from
    # the oldest on (a late frame within timeout_s is refused; after it the id may be used again)
    assembler = SequenceAssembler(timeout_s=1.0)
    image = np.zeros((4, 5), np.uint8)
    for sequence_id, now_s in ((1, 0.0), (2, 0.4), (3, 0.8)):
        assembler.fail(sequence_id, "test", now_s)
    late = assembler.add(FrameInfo(1, 0, 8, 16.0, 4, 0, image), 0.9)
    assert [type(e).__name__ for e in late] == ["RejectedFrame"]
    assembler.expire(1.5)  # 1 and 2 are older than 1 s, 3 is not
    assert list(assembler._finished) == [3]
    fresh = assembler.add(FrameInfo(1, 0, 8, 16.0, 4, 0, image), 1.5)
    assert fresh == [] and assembler.pending_ids == [1]


def _with_references(frames, kinds=("white", "black")):
    """``frames`` of one scan followed by its reference frames (filled with 200 + i)."""
    count = len(frames) + len(kinds)
    out = [FrameInfo(sequence_id=f.sequence_id, pattern_index=f.pattern_index, pattern_count=count,
                     frequency=f.frequency, steps=f.steps, step=f.step, image=f.image, stamp_ns=f.stamp_ns)
           for f in frames]
    for offset, kind in enumerate(kinds):
        index = len(frames) + offset
        out.append(FrameInfo(sequence_id=frames[0].sequence_id, pattern_index=index, pattern_count=count,
                             frequency=0.0, steps=1, step=0, image=np.full(frames[0].image.shape, 200 + offset,
                                                                           dtype=np.uint8), kind=kind))
    return out


@pytest.mark.parametrize("with_layout", [False, True], ids=["triggers", "PatternSequence"])
def test_white_and_black_frames_after_the_fringe_sets_come_out_as_the_scans_references(with_layout):
    from dptpu.messages import PatternEntry, PatternSequence

    assembler = SequenceAssembler(timeout_s=1.0)
    if with_layout:
        sequence = PatternSequence(entries=[PatternEntry(frequency=16.0, steps=4), PatternEntry(frequency=1.0, steps=3),
                                            PatternEntry(kind="white", steps=1), PatternEntry(kind="black", steps=1)],
                                   projector_width=912, projector_height=1140)
        assembler.set_layout(ScanLayout.from_pattern_sequence(sequence))
    frames = _with_references(frames_of(3))
    (scan,) = feed(assembler, frames[::-1])  # any arrival order
    assert isinstance(scan, AssembledScan) and scan.layout.references == ("white", "black")
    assert scan.layout.frequencies == (16.0, 1.0) and scan.frame_count == 7
    assert [int(scan.references[k][0, 0]) for k in ("white", "black")] == [200, 201]
    assert [slot.step for slot in scan.slots()] == [0, 1, 2, 3, 0, 1, 2]  # the fringe frames only


def test_a_reference_frame_where_the_sequence_has_a_fringe_pattern_fails_the_scan():
    from dptpu.messages import PatternEntry, PatternSequence

    assembler = SequenceAssembler(timeout_s=1.0)
    sequence = PatternSequence(entries=[PatternEntry(frequency=16.0, steps=4), PatternEntry(frequency=1.0, steps=3),
                                        PatternEntry(kind="white", steps=1)],
                               projector_width=912, projector_height=1140)
    assembler.set_layout(ScanLayout.from_pattern_sequence(sequence))
    frames = _with_references(frames_of(4), kinds=("black",))
    (dropped,) = feed(assembler, frames[-1:])
    assert isinstance(dropped, DroppedScan)
    assert dropped.reason == "frame pattern 7 (black) is a black frame; the PatternSequence has white at pattern 7"
