"""Pixel layouts of ``sensor_msgs/Image`` encodings (the ROS 2 ``sensor_msgs/image_encodings`` names).

Named encodings: ``mono8``, ``mono16``, ``rgb8``, ``bgr8``, ``rgba8``, ``bgra8``, ``rgb16``, ``bgr16``,
``rgba16``, ``bgra16`` and the Bayer mosaics ``bayer_{rggb,bggr,gbrg,grbg}{8,16}``. Generic encodings
``{8,16,32,64}{U,S,F}C{1..4}`` (e.g. ``32FC1``: one float32 channel) where numpy has that type
(``8UC3``, ``16SC1``, ``32FC1``, ``64FC1``; no ``8FC``, ``16FC`` or ``64UC``).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = ["PixelLayout", "pixel_layout", "default_encoding", "ENCODINGS"]


class PixelLayout(NamedTuple):
    """Element type (native byte order) and channel count of an encoding."""

    dtype: np.dtype
    channels: int


def _build_table() -> dict[str, PixelLayout]:
    table = {
        "mono8": PixelLayout(np.dtype(np.uint8), 1),
        "mono16": PixelLayout(np.dtype(np.uint16), 1),
        "rgb8": PixelLayout(np.dtype(np.uint8), 3),
        "bgr8": PixelLayout(np.dtype(np.uint8), 3),
        "rgba8": PixelLayout(np.dtype(np.uint8), 4),
        "bgra8": PixelLayout(np.dtype(np.uint8), 4),
        "rgb16": PixelLayout(np.dtype(np.uint16), 3),
        "bgr16": PixelLayout(np.dtype(np.uint16), 3),
        "rgba16": PixelLayout(np.dtype(np.uint16), 4),
        "bgra16": PixelLayout(np.dtype(np.uint16), 4),
    }
    for mosaic in ("rggb", "bggr", "gbrg", "grbg"):
        table[f"bayer_{mosaic}8"] = PixelLayout(np.dtype(np.uint8), 1)
        table[f"bayer_{mosaic}16"] = PixelLayout(np.dtype(np.uint16), 1)
    generic = {"8U": np.uint8, "8S": np.int8, "16U": np.uint16, "16S": np.int16, "32S": np.int32,
               "32F": np.float32, "64F": np.float64}
    for prefix, dtype in generic.items():
        for channels in range(1, 5):
            table[f"{prefix}C{channels}"] = PixelLayout(np.dtype(dtype), channels)
    return table


#: Every known encoding name -> :class:`PixelLayout`.
ENCODINGS: dict[str, PixelLayout] = _build_table()

# Encoding chosen by Image.from_array for (dtype, channels) when none is given.
_DEFAULTS = {
    (np.dtype(np.uint8), 1): "mono8",
    (np.dtype(np.uint16), 1): "mono16",
    (np.dtype(np.uint8), 3): "rgb8",
    (np.dtype(np.uint8), 4): "rgba8",
    (np.dtype(np.uint16), 3): "rgb16",
    (np.dtype(np.uint16), 4): "rgba16",
}


def pixel_layout(encoding: str) -> PixelLayout:
    """The :class:`PixelLayout` of ``encoding``; ValueError naming the known encodings if unknown."""
    layout = ENCODINGS.get(encoding) if isinstance(encoding, str) else None
    if layout is None:
        raise ValueError(f"unknown image encoding {encoding!r}; expected one of {', '.join(ENCODINGS)}")
    return layout


def default_encoding(dtype: np.dtype, channels: int) -> str:
    """Encoding for an array of ``dtype`` with ``channels`` channels: ``mono8``, ``mono16``, ``rgb8``,
    ``rgba8``, ``rgb16``, ``rgba16``, else the generic ``{bits}{U,S,F}C{channels}`` (e.g. ``32FC1``).

    Convention: 3- and 4-channel 8/16-bit arrays are taken as RGB(A); pass ``"bgr8"`` for OpenCV images.
    """
    native = np.dtype(dtype).newbyteorder("=")
    name = _DEFAULTS.get((native, channels))
    if name is not None:
        return name
    letter = {"u": "U", "i": "S", "f": "F"}.get(native.kind)
    generic = f"{native.itemsize * 8}{letter}C{channels}"
    if letter is None or generic not in ENCODINGS:
        raise ValueError(f"no image encoding for dtype {native} with {channels} channel(s); expected uint8, "
                         "int8, uint16, int16, int32, float32 or float64 with 1 to 4 channels")
    return generic
