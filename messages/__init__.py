"""Typed messages (ROS 2 field names and semantics) and their ZeroMQ + msgpack wire codec.

- :mod:`.std`: ``Time``, ``Header``.
- :mod:`.sensor`: ``Image``, ``CameraInfo``, ``RegionOfInterest``, ``PointField``, ``PointCloud2``.
- :mod:`.diagnostic`: ``KeyValue``, ``DiagnosticStatus``, ``DiagnosticArray``.
- :mod:`.ros2_definitions`: every type's ROS 2 form (``.msg`` text; the scanner types' shipped ``msg/*.msg``);
  :mod:`.cdr`: every type in ROS 2's CDR (``encode_cdr``, ``decode_cdr``).
- :mod:`.geometry`: ``Vector3``, ``Quaternion``, ``Transform``, ``TransformStamped``; :mod:`.tf`: ``TFMessage``.
- :mod:`.scanner`: ``PatternEntry``, ``PatternSequence``, ``Trigger``, ``TriggerBurst``, ``FringeFrame``,
  ``FringeBurst``, ``PhaseMaps``, ``AbsolutePhase``, ``ScanStatus``.
- the codec: :mod:`.encoder` (``encode(topic, msg) -> frames``), :mod:`.decoder` (``decode(frames) -> (topic,
  msg)``), :mod:`.decode_limits` (``DecodeLimits``), :mod:`.wire_format` (``DecodeError``, ``EncodeError``, the
  frame layout); their parts: :mod:`.codec_plan`, :mod:`.field_encoding`, :mod:`.frame_reading`,
  :mod:`.field_decoding`, :mod:`.fast_decoding`.
- :mod:`.schema`: ``Message`` and ``message()``; :mod:`.field_spec`: the field specifiers.
- :mod:`.registry`: type names such as ``"sensor_msgs/msg/Image"`` to classes.

This package imports numpy and msgpack only (never ``dptpu.graph``, never pickle). Importing it
registers every message type. The wire format is specified in ``docs/messages.md``.
"""

from .decode_limits import DEFAULT_LIMITS, DecodeLimits
from .decoder import decode
from .diagnostic import DiagnosticArray, DiagnosticStatus, KeyValue
from .encoder import encode
from .geometry import Quaternion, Transform, TransformStamped, Vector3
from .registry import lookup, registered_types
from .scanner import (
    AbsolutePhase,
    FringeBurst,
    FringeFrame,
    PatternEntry,
    PatternSequence,
    PhaseMaps,
    ScanStatus,
    Trigger,
    TriggerBurst,
)
from .schema import Message, message_definition
from .sensor import CameraInfo, Image, PointCloud2, PointField, RegionOfInterest
from .std import Header, Time
from .tf import TFMessage
from .wire_format import ALLOWED_DTYPES, DecodeError, EncodeError

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
    "FringeBurst",
    "TriggerBurst",
    "PhaseMaps",
    "AbsolutePhase",
    "ScanStatus",
    "KeyValue",
    "DiagnosticStatus",
    "DiagnosticArray",
    "Vector3",
    "Quaternion",
    "Transform",
    "TransformStamped",
    "TFMessage",
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
