"""FrameBursts: a camera side's frames gathered into an entry's burst (pure logic, time passed in)."""
from __future__ import annotations

import numpy as np
import pytest

from dptpu.messages import FringeBurst, Trigger
from dptpu.messages.decoder import decode
from dptpu.messages.encoder import encode
from dptpu.nodes.frame_bursts import FrameBursts, frames_in_entry

SHAPE = (6, 8)


def triggers_of(sequence_id: int, entries) -> list[Trigger]:
    """The projector's Triggers of one scan: entries ``(frequency, steps)`` or ``"white"`` / ``"black"``."""
    count = sum(1 if isinstance(e, str) else e[1] for e in entries)
    out, index = [], 0
    for entry in entries:
        if isinstance(entry, str):
            out.append(Trigger(sequence_id=sequence_id, pattern_index=index, pattern_count=count, steps=1,
                               kind=entry))
            index += 1
            continue
        frequency, steps = entry
        for step in range(steps):
            out.append(Trigger(sequence_id=sequence_id, pattern_index=index, pattern_count=count,
                               frequency=frequency, steps=steps, step=step))
            index += 1
    return out


def frame_of(trigger: Trigger, dtype=np.uint8) -> np.ndarray:
    """A frame whose pixels say which scan and pattern it is (its first row), the rest a ramp."""
    frame = (np.arange(np.prod(SHAPE)).reshape(SHAPE) % 97).astype(dtype)
    frame[0, :2] = (trigger.sequence_id, trigger.pattern_index)
    return frame


@pytest.fixture
def allocations():
    return []


@pytest.fixture
def bursts(allocations):
    def allocate(shape, dtype):
        allocations.append((shape, np.dtype(dtype)))
        return np.full(shape, 255, dtype)  # not zeros: a frame left unwritten would show

    return FrameBursts(allocate, max_wait_s=0.5)


def feed(bursts, triggers, *, dtype=np.uint8, start_s=0.0, skip=()):
    ready = []
    for k, trigger in enumerate(triggers):
        if trigger.pattern_index in skip:
            continue
        ready += bursts.add(trigger, frame_of(trigger, dtype), 1000 + k, start_s + 0.001 * k)
    return ready


def test_a_scan_of_two_entries_and_references_makes_one_burst_an_entry(bursts, allocations):
    triggers = triggers_of(5, [(64.0, 12), (1.0, 3), "white", "black"])
    ready = feed(bursts, triggers)
    assert [len(b.triggers) for b in ready] == [12, 3, 1, 1]
    assert [t.pattern_index for b in ready for t in b.triggers] == list(range(17))
    assert allocations == [((12, *SHAPE), np.dtype(np.uint8)), ((3, *SHAPE), np.dtype(np.uint8)),
                           ((1, *SHAPE), np.dtype(np.uint8)), ((1, *SHAPE), np.dtype(np.uint8))]
    for burst in ready:
        assert burst.complete
        for trigger, frame in zip(burst.triggers, burst.frames):
            np.testing.assert_array_equal(frame, frame_of(trigger))  # copied, in order
    assert ready[0].last_stamp_ns == 1011 and ready[3].last_stamp_ns == 1016  # the last frame's stamp
    assert bursts.pending is None


def test_a_lost_frame_inside_an_entry_sends_the_burst_short_when_the_next_entry_starts(bursts):
    triggers = triggers_of(7, [(16.0, 4), (1.0, 4)])
    ready = feed(bursts, triggers, skip={2})
    assert [[t.pattern_index for t in b.triggers] for b in ready] == [[0, 1, 3], [4, 5, 6, 7]]
    assert not ready[0].complete and ready[0].frames.shape == (3, *SHAPE)
    np.testing.assert_array_equal(ready[0].frames[2], frame_of(triggers[3]))


def test_a_lost_last_frame_is_sent_by_due_after_the_wait_and_not_before(bursts):
    triggers = triggers_of(9, [(16.0, 4)])
    assert feed(bursts, triggers, skip={3}, start_s=10.0) == []
    assert bursts.due(10.002 + 0.49) == []
    (late,) = bursts.due(10.002 + 0.5)
    assert [t.pattern_index for t in late.triggers] == [0, 1, 2]
    assert bursts.pending is None and bursts.due(20.0) == []


@pytest.mark.parametrize("change", ["next scan", "repeated step", "earlier step", "other size", "other dtype"])
def test_a_frame_that_cannot_join_sends_the_pending_burst_as_it_stands(bursts, change):
    first, second, third = triggers_of(3, [(16.0, 4)])[:3]
    frame = frame_of(third)
    if change == "next scan":
        third = triggers_of(4, [(16.0, 4)])[2]
    elif change == "repeated step":
        third = second
    elif change == "earlier step":
        third = first
    elif change == "other size":
        frame = np.zeros((SHAPE[0] + 1, SHAPE[1]), np.uint8)
    else:
        frame = frame.astype(np.uint16)
    assert bursts.add(first, frame_of(first), 1, 0.0) == [] and bursts.add(second, frame_of(second), 2, 0.0) == []
    (cut,) = bursts.add(third, frame, 3, 0.0)
    assert [t.pattern_index for t in cut.triggers] == [0, 1]
    assert bursts.pending is not None and bursts.pending.triggers == [third]


def test_a_trigger_of_unknown_steps_is_a_burst_of_one():
    assert frames_in_entry(Trigger(steps=0)) == 1 and frames_in_entry(Trigger(steps=1, kind="white")) == 1
    assert frames_in_entry(Trigger(steps=12, step=3)) == 12


def test_a_burst_travels_as_a_fringe_burst_with_its_frames_intact(bursts):
    triggers = triggers_of(2, [(64.0, 3)])
    (burst,) = feed(bursts, triggers, dtype=np.uint16)
    msg = FringeBurst.from_frames(burst.frames, burst.triggers)
    _, decoded = decode(encode("/camera/frame_bursts", msg))
    assert decoded.image.encoding == "mono16" and decoded.image.height == 3 * SHAPE[0]
    np.testing.assert_array_equal(decoded.frames(), np.stack([frame_of(t, np.uint16) for t in triggers]))
    assert [t.step for t in decoded.triggers] == [0, 1, 2]


def test_inconsistent_bursts_are_refused_naming_the_field():
    triggers = triggers_of(2, [(64.0, 3)])
    frames = np.zeros((3, *SHAPE), np.uint8)
    with pytest.raises(ValueError, match="pattern_index must increase"):
        FringeBurst.from_frames(frames, triggers[::-1]).check_consistency()
    with pytest.raises(ValueError, match="of one scan"):
        FringeBurst.from_frames(frames, [*triggers[:2], triggers_of(3, [(64.0, 3)])[2]]).check_consistency()
    with pytest.raises(ValueError, match="N = 2 triggers"):
        FringeBurst.from_frames(frames, triggers[:2])
    with pytest.raises(ValueError, match="max_wait_s"):
        FrameBursts(lambda shape, dtype: np.empty(shape, dtype), max_wait_s=0)
