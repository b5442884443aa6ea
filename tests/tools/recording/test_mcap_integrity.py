"""Damaged MCAP files: every flipped byte is found (chunk, data section and summary CRCs), named by its
record's byte offset, and refused by every reader and by ``dptpu play`` (exit 2, one line, no traceback)."""

from __future__ import annotations

import numpy as np
import pytest
from mcap.stream_reader import StreamReader

from dptpu.cli.main import main
from dptpu.messages import Image
from dptpu.tools.recording import McapReadError, McapRecordWriter, describe_mcap, read_mcap, verify_mcap
from dptpu.tools.recording.mcap_integrity import check_summary_crc, find_corruption

from .sample_messages import sample_messages

COMPRESSIONS = ("none", "lz4", "zstd")


def _write(path, compression, *, compressible=True):
    """Six small images and two PhaseMaps in 4 KiB chunks (compressible: zstd and lz4 really compress)."""
    rng = np.random.default_rng(0)
    with McapRecordWriter(path, compression=compression, chunk_size_bytes=4096) as writer:
        for index in range(6):
            pixels = ((np.arange(40 * 50).reshape(40, 50) % 7) * 30 + index).astype(np.uint8) if compressible \
                else rng.integers(0, 256, (40, 50), dtype=np.uint8)
            writer.write("/camera/image_raw", Image.from_array(pixels), 1_000 + index)
        for index in range(2):  # a dptpu-msgpack channel beside the CDR one
            writer.write("/scanner/phase", sample_messages()["/scanner/phase"], 2_000 + index)
        writer.add_metadata("dptpu.topic_qos", {"/camera/image_raw": "{}"})
    return path.read_bytes()


def _record_offsets(path) -> list[tuple[int, str]]:
    """``(byte offset, record type)`` of every top-level record, read with the mcap library."""
    out = []
    with open(path, "rb") as stream:
        records = iter(StreamReader(stream, emit_chunks=True).records)
        offset = stream.tell()
        for record in records:
            out.append((offset, type(record).__name__))
            offset = stream.tell()
    return out


def _first(path, kind: str) -> int:
    return next(offset for offset, name in _record_offsets(path) if name == kind)


def _flipped(path, data: bytes, offset: int):
    damaged = bytearray(data)
    damaged[offset] ^= 0xFF
    out = path.with_name(f"flipped_{offset}.mcap")
    out.write_bytes(bytes(damaged))
    return out


@pytest.mark.parametrize("compression", COMPRESSIONS)
def test_every_flipped_byte_is_found(tmp_path, compression):
    data = _write(tmp_path / "ok.mcap", compression, compressible=False)
    assert find_corruption(tmp_path / "ok.mcap") is None
    assert check_summary_crc(tmp_path / "ok.mcap") is None
    missed = [offset for offset in range(0, len(data), 53)
              if find_corruption(_flipped(tmp_path, data, offset)) is None]
    assert missed == []


@pytest.mark.parametrize("compression", COMPRESSIONS)
def test_reader_refuses_a_flipped_chunk_byte_naming_the_chunk_offset(tmp_path, compression):
    data = _write(tmp_path / "ok.mcap", compression)
    assert len(list(read_mcap(tmp_path / "ok.mcap"))) == 8
    first_chunk = _first(tmp_path / "ok.mcap", "Chunk")
    assert data[first_chunk] == 0x06  # the Chunk opcode
    bad = _flipped(tmp_path, data, first_chunk + 60)  # inside its records
    with pytest.raises(McapReadError, match=rf"^cannot read .*{bad.name}: corrupt: chunk at byte offset "
                                            rf"{first_chunk}: "):
        list(read_mcap(bad))
    with pytest.raises(McapReadError, match=rf"chunk at byte offset {first_chunk}"):
        list(read_mcap(bad, verify=False))  # the chunk CRC is checked as the chunk is read, too


@pytest.mark.parametrize("compression", COMPRESSIONS)
def test_summary_and_data_section_damage_refused_by_describe_and_verify(tmp_path, compression):
    data = _write(tmp_path / "ok.mcap", compression)
    summary_byte = len(data) - 8 - 29 - 40  # inside the summary section, before the footer
    with pytest.raises(McapReadError, match=r"corrupt: summary section \(byte offset \d+ to the footer at \d+\)"):
        describe_mcap(_flipped(tmp_path, data, summary_byte))
    message_index = _first(tmp_path / "ok.mcap", "MessageIndex")  # outside every chunk: the data section CRC
    damaged = _flipped(tmp_path, data, message_index + 20)
    with pytest.raises(McapReadError, match=r"corrupt: data section \(bytes 0 to the DataEnd record at byte offset "
                                            r"\d+\): its CRC-32 does not match"):
        verify_mcap(damaged)
    assert len(list(read_mcap(damaged, verify=False))) == 8  # the message indexes are not read: only a full check


@pytest.mark.parametrize("compression", COMPRESSIONS)
def test_play_refuses_a_corrupt_file_with_one_line_and_exit_2(tmp_path, capsys, compression):
    data = _write(tmp_path / "ok.mcap", compression)
    first_chunk = _first(tmp_path / "ok.mcap", "Chunk")
    bad = _flipped(tmp_path, data, first_chunk + 100)
    assert main(["play", str(bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "Traceback" not in err
    assert err.startswith(f"dptpu play: error: cannot read {bad}: corrupt: chunk at byte offset {first_chunk}: ")
