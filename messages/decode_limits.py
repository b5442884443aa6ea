"""The upper bounds a received message must respect (:class:`DecodeLimits`)."""

from __future__ import annotations

from dataclasses import dataclass, fields

__all__ = ["DecodeLimits", "DEFAULT_LIMITS"]


@dataclass(frozen=True)
class DecodeLimits:
    """Upper bounds a received message must respect; anything larger raises :class:`DecodeError`.

    Attributes
    ----------
    max_frames : int
        Frames in the multipart message (topic + header + arrays).
    max_total_bytes : int
        Bytes in all frames together.
    max_array_bytes : int
        Bytes of one array.
    max_ndim : int
        Dimensions of one array.
    max_dims_product : int
        Elements of one array (product of its shape).
    max_header_bytes : int
        Bytes of the msgpack header. Parsing it is the only allocation that grows with the input:
        at most about 80 bytes of Python objects per header byte (a header of empty maps), i.e. about
        5 MiB for the default 64 KiB. Arrays are never allocated, only viewed.
    max_topic_bytes : int
        Bytes of the topic name.
    """

    max_frames: int = 2 + 64
    max_total_bytes: int = 1 << 30
    max_array_bytes: int = 512 << 20
    max_ndim: int = 8
    max_dims_product: int = 1 << 29
    max_header_bytes: int = 64 << 10
    max_topic_bytes: int = 1024

    def __post_init__(self):
        for field in fields(self):
            value = getattr(self, field.name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"DecodeLimits.{field.name} must be a positive int; got {value!r}")
        if self.max_frames < 2:
            raise ValueError(f"DecodeLimits.max_frames must be >= 2 (topic and header); got {self.max_frames}")


DEFAULT_LIMITS = DecodeLimits()
