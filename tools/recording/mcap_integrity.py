"""Check an MCAP file's CRCs and framing in one linear pass, naming the byte offset of the first fault.

MCAP protects its bytes with three CRC-32 values (the MCAP specification, "Records"):

- each Chunk's ``uncompressed_crc``: the records inside the chunk, after decompression;
- the DataEnd record's ``data_section_crc``: every byte from the file's first magic up to the DataEnd
  record (chunk headers, message indexes, metadata and attachments included);
- the Footer's ``summary_crc``: the summary section up to and including the footer's
  ``summary_offset_start`` field.

A stored CRC of 0 means "not computed" and is not checked. The records are parsed by the ``mcap``
library and the chunk CRC is its own check (``get_chunk_data_stream(validate_crc=True)``); the data
section CRC is the library's ``StreamReader(validate_crcs=True)`` check; the library has no check of the
summary CRC, which is computed here with :func:`zlib.crc32`.
"""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

from mcap.exceptions import EndOfFile, InvalidMagic, McapError
from mcap.records import Chunk, DataEnd, Footer
from mcap.stream_reader import MAGIC_SIZE, CRCValidationError, StreamReader, breakup_chunk

__all__ = ["find_corruption", "check_summary_crc", "PARSE_ERRORS", "reason"]

#: Footer bytes a summary CRC covers after the summary section: opcode (1), length (8),
#: summary_start (8), summary_offset_start (8).
_FOOTER_BYTES_IN_SUMMARY_CRC = 1 + 8 + 8 + 8
#: What corrupt bytes can raise inside the mcap library's parsers and decompressors: its own errors,
#: struct/EOF errors of a cut record, undecodable strings (ValueError), lz4's RuntimeError and zstandard's
#: ZstdError (an Exception subclass the library does not wrap; caught as a tuple member below).
PARSE_ERRORS: tuple[type[BaseException], ...] = (McapError, ValueError, EOFError, struct.error, RuntimeError,
                                                  MemoryError, OverflowError)
try:  # zstandard is a dependency of mcap's zstd support; without it zstd chunks fail as unsupported
    from zstandard import ZstdError
    PARSE_ERRORS += (ZstdError,)
except ImportError:  # pragma: no cover - mcap then reports zstd chunks as unsupported (an McapError)
    pass


def find_corruption(path: str | Path) -> str | None:
    """Where and how an MCAP file is damaged, or None when every record parses and every CRC matches.

    Parameters
    ----------
    path : str or Path
        An existing ``.mcap`` file.

    Returns
    -------
    str or None
        One line such as ``"chunk at byte offset 1234: its CRC-32 does not match its records (stored
        0x..., computed 0x...)"``; None for an intact file.

    Notes
    -----
    Reads the whole file once and decompresses every chunk (the cost of one playback pass). Offsets are
    those of the start of the record at fault (its opcode byte), counted from the start of the file.
    """
    path = Path(path)
    size = path.stat().st_size
    with open(path, "rb") as stream:
        reader = StreamReader(stream, emit_chunks=True, validate_crcs=True, record_size_limit=size)
        records = iter(reader.records)
        offset = 0
        while True:
            try:
                record = next(records)
            except StopIteration:
                return "no footer (the file ends early; `mcap recover` repairs a recording that was not closed)"
            except CRCValidationError as error:
                return (f"data section (bytes 0 to the DataEnd record at byte offset {offset}): its CRC-32 does not "
                        f"match (stored 0x{error.expected:08x}, computed 0x{error.actual:08x})")
            except InvalidMagic:
                return "byte offset 0: no MCAP magic (not an MCAP file)"
            except EndOfFile:
                return f"record at byte offset {offset or MAGIC_SIZE}: the file ends inside it (truncated)"
            except PARSE_ERRORS as error:
                return f"record at byte offset {offset or MAGIC_SIZE}: {reason(error)}"
            if isinstance(record, Chunk):
                problem = _chunk_problem(record)
                if problem is not None:
                    return f"chunk at byte offset {offset}: {problem}"
            elif isinstance(record, Footer):
                try:
                    next(records, None)  # the reader reads the closing magic after the footer
                except PARSE_ERRORS as error:
                    return f"closing magic at byte offset {stream.tell() - 8}: {reason(error)}"
                return _summary_problem(stream, record, offset)
            elif isinstance(record, DataEnd):
                pass  # the reader checked its CRC (above)
            offset = stream.tell()


def check_summary_crc(path: str | Path) -> str | None:
    """The footer's summary CRC check alone (reads only the summary section): None when it matches or is 0.

    Returns
    -------
    str or None
        What is wrong, with the footer's byte offset; None for an intact summary.
    """
    path = Path(path)
    with open(path, "rb") as stream:
        size = stream.seek(0, 2)
        footer_offset = size - 8 - (_FOOTER_BYTES_IN_SUMMARY_CRC + 4)  # magic (8), footer with its CRC (4)
        if footer_offset < 8:
            return "too short for an MCAP file"
        stream.seek(footer_offset)
        try:
            record = next(iter(StreamReader(stream, skip_magic=True, record_size_limit=size).records))
        except PARSE_ERRORS as error:
            return f"footer at byte offset {footer_offset}: {reason(error)}"
        if not isinstance(record, Footer):
            return f"byte offset {footer_offset}: expected the footer record, found {type(record).__name__}"
        return _summary_problem(stream, record, footer_offset)


def _chunk_problem(chunk: Chunk) -> str | None:
    try:
        breakup_chunk(chunk, validate_crc=True)  # decompresses, checks uncompressed_crc, parses the records
    except CRCValidationError as error:
        return (f"its CRC-32 does not match its records (stored 0x{error.expected:08x}, computed "
                f"0x{error.actual:08x})")
    except PARSE_ERRORS as error:
        return f"its {chunk.compression or 'uncompressed'} records do not read ({reason(error)})"
    return None


def _summary_problem(stream, footer: Footer, footer_offset: int) -> str | None:
    if footer.summary_crc == 0:
        return None
    start = footer.summary_start or footer_offset
    if not 0 < start <= footer_offset:
        return (f"footer at byte offset {footer_offset}: summary_start {footer.summary_start} is outside the file's "
                f"records")
    stream.seek(start)
    computed = zlib.crc32(stream.read(footer_offset - start + _FOOTER_BYTES_IN_SUMMARY_CRC))
    if computed != footer.summary_crc:
        return (f"summary section (byte offset {start} to the footer at {footer_offset}): its CRC-32 does not match "
                f"(stored 0x{footer.summary_crc:08x}, computed 0x{computed:08x})")
    return None


def reason(error: BaseException) -> str:
    """The message of an exception, or its type's name when the message is empty (never "")."""
    return str(error).strip() or type(error).__name__
