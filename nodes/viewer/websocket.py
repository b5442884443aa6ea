"""The server side of the WebSocket protocol (RFC 6455), as much as the viewer needs: stdlib only.

The opening handshake answers a client's ``Sec-WebSocket-Key`` with ``Sec-WebSocket-Accept = base64(SHA-1(key +
GUID))`` (RFC 6455 section 4.2.2). Frames (section 5.2): a byte ``FIN | opcode``, a length byte (7 bits; 126 and
127 announce a 16- or 64-bit big-endian length), a 4-byte mask and masked payload in every client frame; server
frames are never masked. Opcodes: 1 text, 2 binary, 8 close, 9 ping, 10 pong. Fragmented client messages
(continuation frames) are refused with close code 1003: the viewer's page sends nothing but control frames.
"""
from __future__ import annotations

import base64
import hashlib
import struct

import numpy as np

__all__ = ["GUID", "accept_key", "encode_frame", "read_frame", "OP_TEXT", "OP_BINARY", "OP_CLOSE", "OP_PING",
           "OP_PONG", "ProtocolError", "MAX_CLIENT_PAYLOAD"]

GUID = "258EAFA5-E914-47DA-95CA-C5AB0DC85B11"
OP_CONTINUATION, OP_TEXT, OP_BINARY, OP_CLOSE, OP_PING, OP_PONG = 0x0, 0x1, 0x2, 0x8, 0x9, 0xA
#: Largest client frame accepted, bytes (the page sends only control frames of at most 125 bytes).
MAX_CLIENT_PAYLOAD = 1 << 16


class ProtocolError(ValueError):
    """A client frame that breaks RFC 6455 (unmasked, fragmented, oversized); ``code`` is the close code."""

    def __init__(self, message: str, code: int = 1002):
        super().__init__(message)
        self.code = code


def accept_key(key: str) -> str:
    """``Sec-WebSocket-Accept`` for a client's ``Sec-WebSocket-Key`` (RFC 6455 section 4.2.2).

    Raises
    ------
    ValueError
        When ``key`` is not the base64 text of 16 bytes.
    """
    try:
        raw = base64.b64decode(key.strip(), validate=True)
    except (ValueError, TypeError):
        raw = b""
    if len(raw) != 16:
        raise ValueError(f"Sec-WebSocket-Key must be the base64 text of 16 bytes; got {key!r}")
    return base64.b64encode(hashlib.sha1((key.strip() + GUID).encode("ascii")).digest()).decode("ascii")


def encode_frame(opcode: int, payload: bytes | memoryview = b"") -> list:
    """One unmasked, unfragmented server frame as ``[header, payload]`` (send both; the payload is not copied)."""
    size = len(payload) if not isinstance(payload, memoryview) else payload.nbytes
    first = 0x80 | opcode
    if size < 126:
        header = struct.pack("!BB", first, size)
    elif size < 1 << 16:
        header = struct.pack("!BBH", first, 126, size)
    else:
        header = struct.pack("!BBQ", first, 127, size)
    return [header, payload]


def _read_exactly(stream, count: int) -> bytes:
    data = stream.read(count)
    if data is None or len(data) != count:
        raise EOFError("the WebSocket client closed the connection")
    return data


def read_frame(stream) -> tuple[int, bytes]:
    """Read one client frame from a binary file-like ``stream``: ``(opcode, unmasked payload)``.

    Raises
    ------
    ProtocolError
        For an unmasked frame, a fragment, reserved bits, or a payload over :data:`MAX_CLIENT_PAYLOAD`.
    EOFError
        When the connection ends.
    """
    first, second = _read_exactly(stream, 2)
    if first & 0x70:
        raise ProtocolError("reserved bits set in a client frame (no extension was negotiated)")
    if not first & 0x80 or (first & 0x0F) == OP_CONTINUATION:
        raise ProtocolError("fragmented client messages are not accepted by the viewer", code=1003)
    if not second & 0x80:
        raise ProtocolError("client frames must be masked (RFC 6455 section 5.3)")
    size = second & 0x7F
    if size == 126:
        size = struct.unpack("!H", _read_exactly(stream, 2))[0]
    elif size == 127:
        size = struct.unpack("!Q", _read_exactly(stream, 8))[0]
    if size > MAX_CLIENT_PAYLOAD:
        raise ProtocolError(f"client frame of {size} bytes; at most {MAX_CLIENT_PAYLOAD} accepted", code=1009)
    mask = np.frombuffer(_read_exactly(stream, 4), dtype=np.uint8)
    masked = np.frombuffer(_read_exactly(stream, size), dtype=np.uint8)
    payload = (masked ^ np.resize(mask, size)).tobytes()  # octet i XOR mask[i mod 4]
    return first & 0x0F, payload
