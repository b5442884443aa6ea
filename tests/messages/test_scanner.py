"""The scanner's own messages: pattern sequences, triggers, phase maps, absolute phase, status."""

from __future__ import annotations

import numpy as np
import pytest

from dptpu.messages import (
    AbsolutePhase,
    FringeFrame,
    Image,
    PatternEntry,
    PatternSequence,
    PhaseMaps,
    ScanStatus,
    Trigger,
    decode,
    encode,
)


def _sequence(**changes) -> PatternSequence:
    values = dict(entries=[PatternEntry(frequency=96.0, steps=12), PatternEntry(period=114.0, steps=4),
                           PatternEntry(frequency=1.0, steps=12)],
                  fringe_axis="x", projector_width=912, projector_height=1140, shift_sign=-1)
    values.update(changes)
    return PatternSequence(**values)


def test_pattern_sequence_counts_locates_and_derives_frequencies():
    sequence = _sequence()
    assert sequence.pattern_count == 28
    assert sequence.extent_px == 912 and sequence.projector_size == (912, 1140)
    assert sequence.frequencies() == [96.0, 8.0, 1.0]  # 912 / 114 = 8 periods
    assert sequence.locate(0) == (0, 0)
    assert sequence.locate(11) == (0, 11)
    assert sequence.locate(12) == (1, 0)
    assert sequence.locate(15) == (1, 3)
    assert sequence.locate(27) == (2, 11)
    assert _sequence(fringe_axis="y").extent_px == 1140
    assert _sequence(fringe_axis="y").frequencies()[1] == 1140 / 114.0
    with pytest.raises(ValueError, match=r"pattern_index must be an int in \[0, 28\); got 28"):
        sequence.locate(28)
    _, decoded = decode(encode("/projector/sequence", sequence))
    assert decoded == sequence and decoded.entries[1].period == 114.0


@pytest.mark.parametrize(("changes", "match"), [
    (dict(fringe_axis="z"), r"PatternSequence.fringe_axis must be 'x' or 'y'; got 'z'"),
    (dict(shift_sign=0), r"PatternSequence.shift_sign must be -1 or \+1; got 0"),
    (dict(projector_height=0), r"PatternSequence projector size must be positive; got \(912, 0\)"),
    (dict(entries=[PatternEntry(frequency=8.0, steps=2)]), r"PatternEntry.steps must be >= 3; got 2"),
    (dict(entries=[PatternEntry(steps=4)]), r"PatternEntry needs exactly one of frequency"),
    (dict(entries=[PatternEntry(frequency=float("nan"), steps=4)]), r"got frequency nan, period 0.0"),
])
def test_pattern_sequence_checks(changes, match):
    with pytest.raises(ValueError, match=match):
        encode("/projector/sequence", _sequence(**changes))


def test_trigger_and_fringe_frame_round_trip():
    trigger = Trigger(sequence_id=2**32 - 1, pattern_index=27, pattern_count=28, frequency=1.0, steps=12, step=11)
    image = Image.from_array(np.full((6, 8), 200, np.uint8))
    topic, decoded = decode(encode("/camera/image_raw", FringeFrame(image=image, trigger=trigger)),
                            expected_type=FringeFrame)
    assert decoded.trigger == trigger and decoded.trigger.sequence_id == 4_294_967_295
    assert decoded.image.to_array().sum() == 200 * 48
    with pytest.raises(ValueError, match=r"Trigger.step must be < steps 12; got 12"):
        encode("/t", Trigger(steps=12, step=12))
    with pytest.raises(ValueError, match=r"Trigger.pattern_index must be < pattern_count 28; got 28"):
        encode("/t", Trigger(pattern_index=28, pattern_count=28))


def test_phase_maps_shapes_are_checked():
    phases = np.zeros((2, 3, 4), np.float32)
    good = PhaseMaps(frequencies=np.array([8.0, 1.0]), phases=phases, modulation=phases.copy(),
                     valid=np.ones((3, 4), bool), projector_width=912, projector_height=1140)
    assert good.extent_px == 912
    _, decoded = decode(encode("/scanner/phase", good))
    assert decoded.phases.shape == (2, 3, 4) and decoded.frequencies.tolist() == [8.0, 1.0]
    with pytest.raises(ValueError, match=r"PhaseMaps.modulation must have the shape of phases \(2, 3, 4\); got "
                                         r"\(1, 3, 4\)"):
        encode("/p", PhaseMaps(frequencies=np.array([8.0, 1.0]), phases=phases, modulation=phases[:1],
                               valid=np.ones((3, 4), bool)))
    with pytest.raises(ValueError, match=r"PhaseMaps.valid must have shape \(H, W\) = \(3, 4\); got \(4, 3\)"):
        encode("/p", PhaseMaps(frequencies=np.array([8.0, 1.0]), phases=phases, modulation=phases,
                               valid=np.ones((4, 3), bool)))


def test_absolute_phase_geometry_and_defaults():
    msg = AbsolutePhase(fringe_axis="y", projector_width=912, projector_height=1140)
    assert msg.projector_size == (912, 1140) and msg.extent_px == 1140
    _, decoded = decode(encode("/scanner/absolute_phase", msg))
    assert decoded.absolute_phase.shape == (0, 0) and decoded.absolute_phase.dtype == np.float32
    assert decoded.fringe_order.dtype == np.int32 and decoded.valid.dtype == np.bool_


def test_scan_status_levels_and_states():
    assert (ScanStatus.OK, ScanStatus.WARN, ScanStatus.ERROR, ScanStatus.STALE) == (0, 1, 2, 3)
    status = ScanStatus(sequence_id=5, level=ScanStatus.ERROR, state="failed", reason="no modulation",
                        valid_pixels=0, total_pixels=100)
    _, decoded = decode(encode("/scanner/status", status))
    assert decoded.level == 2 and decoded.state == "failed" and decoded.reason == "no modulation"
    with pytest.raises(ValueError, match=r"ScanStatus.level must be OK \(0\), WARN \(1\), ERROR \(2\) or STALE \(3\); "
                                         r"got 4"):
        encode("/s", ScanStatus(level=4))
    with pytest.raises(ValueError, match=r"ScanStatus.state must be one of idle, capturing, processing, done, "
                                         r"failed; got 'asleep'"):
        encode("/s", ScanStatus(state="asleep"))
    with pytest.raises(ValueError, match=r"ScanStatus.valid_pixels must be <= total_pixels 10; got 11"):
        encode("/s", ScanStatus(valid_pixels=11, total_pixels=10))
