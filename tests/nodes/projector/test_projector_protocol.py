"""The dptpu-trigger/1 line protocol and the trigger-box emulator's state machine (no I/O)."""

from __future__ import annotations

import pytest

from dptpu.messages import PatternEntry, PatternSequence
from dptpu.nodes.projector.emulator import TriggerBoxEmulator
from dptpu.nodes.projector.protocol import (
    MAX_LINE_BYTES,
    Command,
    ProtocolError,
    Reply,
    SequenceSpec,
    encode_command,
    encode_reply,
    format_sequence_spec,
    parse_command,
    parse_reply,
    parse_sequence_spec,
)

SPEC = SequenceSpec("x", (912, 1140), 8333, ((96.0, 12), (10.9, 3)))


def test_commands_encode_to_documented_lines_and_parse_back():
    lines = {Command("HELLO"): b"HELLO\n", Command("STOP"): b"STOP\n",
             Command("START", scan_id=4294967295): b"START 4294967295\n",
             Command("LOAD", sequence=SPEC): b"LOAD x 912 1140 8333 96x12,10.9x3\n"}
    for command, line in lines.items():
        assert encode_command(command) == line
        assert parse_command(line) == command


def test_replies_encode_and_parse_back():
    replies = [Reply("HELLO", protocol="dptpu-trigger/1", firmware="fw-2.1"), Reply("LOADED", count=27),
               Reply("STARTED", scan_id=7), Reply("ACK", scan_id=7, index=26), Reply("DONE", scan_id=7, count=27),
               Reply("ABORT", scan_id=7, count=5, code="DLP_FAULT", text="pattern 5 not confirmed"),
               Reply("STOPPED"), Reply("ERR", code="NOSEQ", text="send LOAD first")]
    for reply in replies:
        line = encode_reply(reply)
        assert line.endswith(b"\n") and len(line) <= MAX_LINE_BYTES + 1
        assert parse_reply(line) == reply
    assert encode_reply(Reply("ACK", scan_id=3, index=11)) == b"ACK 3 11\n"


@pytest.mark.parametrize("line, match", [
    (b"\xff\xfe\x00garbage\x81", "not ASCII"),
    (b"ACK x y", "scan_id must be an integer"),
    (b"ACK 4294967296 1", r"scan_id must be an integer in \[0, 4294967295\]"),
    (b"ACK 1", "ACK takes 2 argument"),
    (b"HELLO", "is a command, not a reply"),
    (b"START 3", "is a command, not a reply"),
    (b"HELLO other-proto/2 fw", "speaks 'other-proto/2'"),
    (b"ERR OOPS bad", "ERR needs a code"),
    (b"%%&*(", "not a dptpu-trigger/1 reply"),
    (b"ACK  1 2", "stray spaces"),
    (b"A" * 200, "longer than 120"),
    (b"", "empty line"),
])
def test_garbage_lines_raise_protocol_error_naming_the_problem(line, match):
    with pytest.raises(ProtocolError, match=match):
        parse_reply(line)


def test_sequence_spec_text_round_trip_and_errors():
    assert parse_sequence_spec("96x12,1x12") == ((96.0, 12), (1.0, 12))
    assert parse_sequence_spec(" 10.9 x 3 ") == ((10.9, 3),)
    assert format_sequence_spec(((96.0, 12), (10.9, 3))) == "96x12,10.9x3"
    with pytest.raises(ValueError, match="steps >= 3"):
        parse_sequence_spec("96x2")
    with pytest.raises(ValueError, match="must be <frequency>x<steps>"):
        parse_sequence_spec("96;12")
    with pytest.raises(ValueError, match="fringe_axis must be 'x' or 'y'"):
        SequenceSpec("z", (912, 1140), 8333, ((1.0, 3),))
    with pytest.raises(ValueError, match="exposure_us must be an integer"):
        SequenceSpec("x", (912, 1140), 50, ((1.0, 3),))


def test_spec_locate_agrees_with_pattern_sequence_message():
    spec = SequenceSpec("y", (912, 1140), 8333, parse_sequence_spec("96x12,1x12"))
    message = PatternSequence(fringe_axis="y", projector_width=912, projector_height=1140,
                              entries=[PatternEntry(frequency=f, steps=n) for f, n in spec.entries])
    assert spec.pattern_count == message.pattern_count == 24
    for index in range(24):
        entry, step = message.locate(index)
        assert spec.locate(index) == (message.entries[entry].frequency, message.entries[entry].steps, step)
    assert spec.locate(13) == (1.0, 12, 1)


def test_emulator_acknowledges_each_pattern_one_exposure_apart():
    box = TriggerBoxEmulator(start_delay_s=0.0)
    box.receive(b"HELLO", 0.0)
    box.receive(b"LOAD x 912 1140 2000 8x3,1x3", 0.0)
    assert box.due(0.0) == [b"HELLO dptpu-trigger/1 emulator-1.0\n", b"LOADED 6\n"]
    box.receive(b"START 9", 1.0)
    times = []
    now = 1.0
    while box.next_due() is not None:
        now = box.next_due()
        times += [(now, line) for line in box.due(now)]
    acks = [f"ACK 9 {i}\n".encode() for i in range(6)]
    assert [line for _, line in times] == [b"STARTED 9\n", *acks, b"DONE 9 6\n"]
    ack_times = [t for t, line in times if line.startswith(b"ACK")]
    assert ack_times == pytest.approx([1.0 + 0.002 * i for i in range(6)])  # exposure_us = 2000


def test_emulator_refuses_start_before_load_and_during_a_scan_and_aborts_on_fault():
    box = TriggerBoxEmulator(abort_after=2, start_delay_s=0.0)
    box.receive(b"START 1", 0.0)
    assert box.due(0.0) == [b"ERR NOSEQ no sequence loaded; send LOAD first\n"]
    box.receive(b"LOAD y 912 1140 1000 4x4", 0.0)
    box.receive(b"START 1", 0.0)
    box.receive(b"START 2", 0.0005)
    box.receive(b"FLASH", 0.0005)
    lines = box.due(1.0)
    assert b"ERR BUSY a scan is running; send STOP first\n" in lines
    assert any(line.startswith(b"ERR BADCMD unknown command") for line in lines)
    assert [line for line in lines if line.startswith((b"ACK", b"ABORT", b"DONE"))] == [
        b"ACK 1 0\n", b"ACK 1 1\n", b"ABORT 1 2 DLP_FAULT pattern 2 not confirmed by the DLP\n"]


def test_emulator_keeps_a_bounded_command_history_over_thousands_of_scans():
    """The loop:// projector's memory grew linearly (+3 % over 6000 scans, issue 19): the emulator kept every
    command. It keeps the last COMMANDS_KEPT, and every scan is still answered."""
    from dptpu.nodes.projector.emulator import COMMANDS_KEPT

    box = TriggerBoxEmulator(start_delay_s=0.0)
    box.receive(b"LOAD x 912 1140 1000 4x3", 0.0)
    now, done = 0.0, 0
    for scan in range(1, 6001):
        box.receive(f"START {scan}".encode(), now)
        while box.next_due() is not None:
            now = box.next_due()
            done += sum(line.startswith(b"DONE") for line in box.due(now))
    assert done == 6000
    assert len(box.commands) == COMMANDS_KEPT
    assert box.commands[-1] == parse_command(b"START 6000")


def test_reference_frames_end_the_sequence_and_travel_in_the_load_line():
    from dptpu.nodes.projector.protocol import split_references

    assert split_references("64x12,1x12,White,black") == ("64x12,1x12", ("white", "black"))
    with pytest.raises(ValueError, match="reference frames \\(white, black\\) come after the fringe sets"):
        split_references("white,64x12")
    spec = SequenceSpec("x", (912, 1140), 8333, ((64.0, 12), (1.0, 12)), ("white", "black"))
    assert spec.pattern_count == 26
    assert (spec.locate(23), spec.kind_of(23)) == ((1.0, 12, 11), "phase")
    assert (spec.locate(24), spec.kind_of(24), spec.kind_of(25)) == ((0.0, 1, 0), "white", "black")
    line = encode_command(Command("LOAD", sequence=spec))
    assert line == b"LOAD x 912 1140 8333 64x12,1x12,white,black\n"
    assert parse_command(line).sequence == spec
    with pytest.raises(ValueError, match="references must be 'white' and/or 'black', each at most once"):
        SequenceSpec("x", (912, 1140), 8333, ((64.0, 12),), ("white", "white"))
