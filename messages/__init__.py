"""Typed messages (ROS 2 field names and semantics) and their ZeroMQ + msgpack wire codec.

- :mod:`.std`: ``Time``, ``Header``.
- :mod:`.sensor`: ``Image``, ``CameraInfo``, ``RegionOfInterest``, ``PointField``, ``PointCloud2``.
- :mod:`.scanner`: ``PatternEntry``, ``PatternSequence``, ``Trigger``, ``FringeFrame``, ``PhaseMaps``,
  ``AbsolutePhase``, ``ScanStatus``.
- :mod:`.codec`: ``encode(topic, msg) -> frames``, ``decode(frames) -> (topic, msg)``, ``DecodeError``,
  ``DecodeLimits``.
- :mod:`.registry`: type names such as ``"sensor_msgs/msg/Image"`` to classes.

This package imports numpy and msgpack only (never ``dptpu.graph``, never pickle). Importing it
registers every message type. The wire format is specified in ``docs/messages.md``.
"""

from .codec import ALLOWED_DTYPES, DEFAULT_LIMITS, DecodeError, DecodeLimits, EncodeError, decode, encode
from .registry import lookup, registered_types
from .scanner import AbsolutePhase, FringeFrame, PatternEntry, PatternSequence, PhaseMaps, ScanStatus, Trigger
from .schema import Message, message_definition
from .sensor import CameraInfo, Image, PointCloud2, PointField, RegionOfInterest
from .std import Header, Time

__all__ = [
    "Time",
    "Header",
    "Image",
    "CameraInfo",
    "RegionOfInterest",
    "PointField",
    "PointCloud2",
    "PatternEntry",
    "PatternSequence",
    "Trigger",
    "FringeFrame",
    "PhaseMaps",
    "AbsolutePhase",
    "ScanStatus",
    "Message",
    "encode",
    "decode",
    "DecodeError",
    "EncodeError",
    "DecodeLimits",
    "DEFAULT_LIMITS",
    "ALLOWED_DTYPES",
    "lookup",
    "registered_types",
    "message_definition",
]
