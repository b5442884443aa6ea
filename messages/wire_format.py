"""The wire format both directions share: frame layout constants, the allowed dtypes, the codec's errors.

Frame layout (``docs/messages.md`` has the full specification)::

    frame 0      topic, UTF-8 bytes, e.g. b"/camera/image_raw"
    frame 1      header, one msgpack map:
                   {"wire": 1, "type": "sensor_msgs/msg/Image", "version": 1,
                    "fields": {...scalars, nested maps, inline sequences; each bulk array replaced by
                               msgpack ext type 1 holding its index, big-endian uint32...},
                    "arrays": [[dtype, [dim0, dim1, ...]], ...]}
    frame 2 + i  the raw bytes of array i, C order, little-endian

:mod:`.encoder` writes it, :mod:`.decoder` reads it; neither uses pickle or eval.
"""

from __future__ import annotations

import struct
from typing import Any

import numpy as np

from .field_spec import ARRAY_DTYPES, INTEGER_RANGES

__all__ = ["WIRE_VERSION", "ARRAY_REF_EXT_CODE", "ALLOWED_DTYPES", "HEADER_KEYS", "HEADER_KEY_SET", "SCALAR_CHECKS",
           "ARRAY_INDEX", "DecodeError", "EncodeError", "short_repr"]

#: Version of the frame layout and header keys (not of any message type).
WIRE_VERSION = 1

#: The only msgpack extension type in a header: a reference to array frame ``2 + index``.
ARRAY_REF_EXT_CODE = 1

#: Wire dtype strings a decoder accepts (numpy ``dtype.str``), all little-endian or single-byte.
ALLOWED_DTYPES: dict[str, np.dtype] = {dtype.str: dtype for dtype in ARRAY_DTYPES.values()}

#: The header's keys, in the order the encoder writes them.
HEADER_KEYS = ("wire", "type", "version", "fields", "arrays")
HEADER_KEY_SET = frozenset(HEADER_KEYS)

#: primitive -> (exact Python type on the wire, inclusive integer range or None).
SCALAR_CHECKS: dict[str, tuple[type[Any], int | None, int | None]] = {
    "string": (str, None, None), "float64": (float, None, None), "bool": (bool, None, None),
    **{name: (int, low, high) for name, (low, high) in INTEGER_RANGES.items()}}

#: An array reference's payload: the array's index, big-endian uint32.
ARRAY_INDEX = struct.Struct(">I")


class DecodeError(ValueError):
    """A received message is malformed, oversized, of an unexpected type or of another schema version."""


class EncodeError(ValueError):
    """A message cannot be encoded: a field has the wrong type, dtype, shape or range."""


def short_repr(value) -> str:
    """``repr(value)`` cut to 60 characters, for error messages."""
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."
