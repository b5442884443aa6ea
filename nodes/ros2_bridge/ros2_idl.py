"""ROS 2's DDS types of the bridged messages, as Cyclone DDS IDL dataclasses, and the conversions from ours.

A ROS 2 node on ``rmw_cyclonedds_cpp`` publishes ``sensor_msgs/msg/PointCloud2`` as the DDS type
``sensor_msgs::msg::dds_::PointCloud2_`` (``rosidl_generator_dds_idl``: package ``::msg::dds_::`` name ``_``) in
plain CDR (XCDR1), with the members of the ``.msg`` file in order and ROS's primitive types (``uint8[]`` is
``sequence<uint8>``). These classes declare exactly that, so the bridge's samples are byte for byte what a ROS 2
driver sends, and a ROS 2 subscriber takes them like any driver's.

Services follow ``rmw_cyclonedds_cpp`` too: ``/scanner/capture`` (``std_srvs/srv/Trigger``) is the request topic
``rq/scanner/captureRequest`` and the reply topic ``rr/scanner/captureReply``; every sample starts with the
request header ``{uint64 client_guid; int64 sequence_number}`` that rmw_cyclonedds puts before the request or
response members, and the reply repeats the request's header.

Bulk ``data`` members are declared ``sequence<uint8>`` (so the type information is ROS's), but the two types
that carry them (``PointCloud2_``, ``Image_``) serialize through :class:`CdrWriter` and deserialize through
:class:`CdrReader` (buffers copied whole, no per-byte Python objects: Cyclone's own code makes one int per
byte; docs/benchmarks.md, "bridge"); ``tests/nodes/ros2_bridge/test_ros2_bridge_idl.py`` checks both against
Cyclone's own serializer.
"""
# no `from __future__ import annotations`: Cyclone DDS resolves these classes' annotations at run time

import struct
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Annotated

import numpy as np
from cyclonedds.idl import IdlStruct
from cyclonedds.idl._support import Endianness
from cyclonedds.idl.types import array, byte, float64, int32, int64, sequence, uint8, uint32, uint64

from dptpu.messages import CameraInfo, DiagnosticArray, Image, PointCloud2, TFMessage

__all__ = [
    "Time_", "Header_", "PointField_", "PointCloud2_", "Image_", "RegionOfInterest_", "CameraInfo_",
    "KeyValue_", "DiagnosticStatus_", "DiagnosticArray_", "Vector3_", "Quaternion_", "Transform_",
    "TransformStamped_", "TFMessage_", "Trigger_Request_", "Trigger_Response_", "CdrWriter",
    "CdrReader", "to_dds", "dds_type_of", "ros_topic_name",
    "CDR_LE_HEADER",
]

# Cyclone's `sequence[T]` and `array[T, n]` build these Annotated types at run time; spelled out, the type checker
# reads them too (it takes Cyclone's subscripts for plain classes, and `9` for a type).
Octets = Annotated[Sequence[uint8], sequence(uint8)]
Float64s = Annotated[Sequence[float64], sequence(float64)]
Float64x9 = Annotated[Sequence[float64], array(float64, 9)]
Float64x12 = Annotated[Sequence[float64], array(float64, 12)]

#: Encapsulation header of plain CDR, little-endian (RTPS ``CDR_LE``): what rmw_cyclonedds writes.
CDR_LE_HEADER = b"\x00\x01\x00\x00"


class CdrWriter:
    """Plain CDR (XCDR1) little-endian encoder: primitives aligned to their size from the start of the body.

    Bulk ``sequence<uint8>`` payloads are kept as buffers and joined once by :meth:`getvalue`, so a 6 MB
    cloud is copied once here.
    """

    def __init__(self) -> None:
        self._parts: list = [CDR_LE_HEADER]
        self._head = bytearray()   # bytes written since the last bulk part
        self._offset = 0           # body offset (the 4-byte encapsulation header excluded)

    def _align(self, size: int) -> None:
        pad = -self._offset % size
        if pad:
            self._head += b"\x00" * pad
            self._offset += pad

    def _pack(self, fmt: str, size: int, *values) -> None:
        self._align(size)
        self._head += struct.pack("<" + fmt, *values)
        self._offset += struct.calcsize("<" + fmt)

    def u8(self, value: int) -> None:
        self._head.append(value & 0xFF)
        self._offset += 1

    def boolean(self, value: bool) -> None:
        self.u8(1 if value else 0)

    def i32(self, value: int) -> None:
        self._pack("i", 4, value)

    def u32(self, value: int) -> None:
        self._pack("I", 4, value)

    def string(self, value: str) -> None:
        raw = value.encode("utf-8") + b"\x00"
        self.u32(len(raw))
        self._head += raw
        self._offset += len(raw)

    def octets(self, data) -> None:
        """``sequence<uint8>``: uint32 length, then the bytes of ``data`` (any C-contiguous buffer)."""
        view = memoryview(data).cast("B")
        self.u32(view.nbytes)
        self._parts.append(bytes(self._head))
        self._parts.append(view)
        self._head = bytearray()
        self._offset += view.nbytes

    def header(self, stamp_sec: int, stamp_nanosec: int, frame_id: str) -> None:
        """``std_msgs::msg::dds_::Header_``: ``{Time_ stamp {int32 sec; uint32 nanosec}; string frame_id}``."""
        self.i32(stamp_sec)
        self.u32(stamp_nanosec)
        self.string(frame_id)

    def getvalue(self) -> bytes:
        """The serialized sample (encapsulation header included), padded to a multiple of 4 bytes."""
        self._head += b"\x00" * (-self._offset % 4)  # the body starts 4-aligned after the 4-byte header
        self._parts.append(bytes(self._head))
        return b"".join(self._parts)


class CdrReader:
    """Plain CDR (XCDR1) decoder of one serialized sample (encapsulation header first); the inverse of
    :class:`CdrWriter`. ``sequence<uint8>`` members come back as ``bytes`` slices (one copy, no int objects).

    Raises
    ------
    ValueError
        When the sample is not little- or big-endian plain CDR, or ends early.
    """

    def __init__(self, data):
        self._data = memoryview(data).cast("B")
        if self._data.nbytes < 4 or self._data[0] != 0 or self._data[1] not in (0, 1):
            raise ValueError(f"expected a plain CDR sample (encapsulation 0x0000 or 0x0001); got "
                             f"{bytes(self._data[:4]).hex()}")
        self._endian = "<" if self._data[1] == 1 else ">"
        self._pos = 4

    def _take(self, size: int, align: int = 1) -> memoryview:
        self._pos += -(self._pos - 4) % align
        if self._pos + size > self._data.nbytes:
            raise ValueError(f"the CDR sample ends at byte {self._data.nbytes}; a member needs {size} bytes at "
                             f"{self._pos}")
        chunk = self._data[self._pos:self._pos + size]
        self._pos += size
        return chunk

    def u8(self) -> int:
        return self._take(1)[0]

    def boolean(self) -> bool:
        return bool(self.u8())

    def i32(self) -> int:
        return struct.unpack(self._endian + "i", self._take(4, 4))[0]

    def u32(self) -> int:
        return struct.unpack(self._endian + "I", self._take(4, 4))[0]

    def string(self) -> str:
        size = self.u32()
        return bytes(self._take(size))[:-1].decode("utf-8") if size else ""

    def octets(self) -> bytes:
        return bytes(self._take(self.u32()))

    def header(self) -> "Header_":
        return Header_(stamp=Time_(sec=self.i32(), nanosec=self.u32()), frame_id=self.string())


@dataclass
class Time_(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    sec: int32 = 0
    nanosec: uint32 = 0


@dataclass
class Header_(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
    stamp: Time_ = field(default_factory=Time_)
    frame_id: str = ""


@dataclass
class PointField_(IdlStruct, typename="sensor_msgs::msg::dds_::PointField_"):
    name: str = ""
    offset: uint32 = 0
    datatype: uint8 = 0
    count: uint32 = 0


@dataclass
class PointCloud2_(IdlStruct, typename="sensor_msgs::msg::dds_::PointCloud2_"):
    """``sensor_msgs/msg/PointCloud2``; ``data`` may be any uint8 buffer (ndarray, bytes) when sent."""

    header: Header_ = field(default_factory=Header_)
    height: uint32 = 0
    width: uint32 = 0
    fields: Annotated[Sequence[PointField_], sequence(PointField_)] = field(default_factory=list)
    is_bigendian: bool = False
    point_step: uint32 = 0
    row_step: uint32 = 0
    data: Octets = field(default_factory=list)
    is_dense: bool = False

    def serialize(self, buffer=None, endianness=None, use_version_2=None) -> bytes:
        """XCDR1 little-endian through :class:`CdrWriter` (XCDR2 or other requests: Cyclone's serializer)."""
        if use_version_2 or buffer is not None or endianness not in (None, _LITTLE):
            return _as_library_sample(self).serialize(buffer=buffer, endianness=endianness,
                                                      use_version_2=use_version_2)
        writer = CdrWriter()
        writer.header(self.header.stamp.sec, self.header.stamp.nanosec, self.header.frame_id)
        writer.u32(self.height)
        writer.u32(self.width)
        writer.u32(len(self.fields))
        for point_field in self.fields:
            writer.string(point_field.name)
            writer.u32(point_field.offset)
            writer.u8(point_field.datatype)
            writer.u32(point_field.count)
        writer.boolean(self.is_bigendian)
        writer.u32(self.point_step)
        writer.u32(self.row_step)
        writer.octets(_octet_buffer(self.data))
        writer.boolean(self.is_dense)
        return writer.getvalue()

    @classmethod
    def deserialize(cls, data, has_header=True, use_version_2=None):
        """From plain CDR through :class:`CdrReader` (``data`` as bytes); other forms: Cyclone's deserializer."""
        if not has_header or use_version_2 or bytes(data[:2]) not in (b"\x00\x00", b"\x00\x01"):
            return super().deserialize(data, has_header=has_header, use_version_2=use_version_2)
        reader = CdrReader(data)
        header, height, width = reader.header(), reader.u32(), reader.u32()
        fields = [PointField_(name=reader.string(), offset=reader.u32(), datatype=reader.u8(), count=reader.u32())
                  for _ in range(reader.u32())]
        return cls(header=header, height=height, width=width, fields=fields, is_bigendian=reader.boolean(),
                   point_step=reader.u32(), row_step=reader.u32(), data=reader.octets(), is_dense=reader.boolean())


@dataclass
class Image_(IdlStruct, typename="sensor_msgs::msg::dds_::Image_"):
    """``sensor_msgs/msg/Image``; ``data`` may be any uint8 buffer when sent."""

    header: Header_ = field(default_factory=Header_)
    height: uint32 = 0
    width: uint32 = 0
    encoding: str = ""
    is_bigendian: uint8 = 0
    step: uint32 = 0
    data: Octets = field(default_factory=list)

    def serialize(self, buffer=None, endianness=None, use_version_2=None) -> bytes:
        """XCDR1 little-endian through :class:`CdrWriter` (XCDR2 or other requests: Cyclone's serializer)."""
        if use_version_2 or buffer is not None or endianness not in (None, _LITTLE):
            return _as_library_sample(self).serialize(buffer=buffer, endianness=endianness,
                                                      use_version_2=use_version_2)
        writer = CdrWriter()
        writer.header(self.header.stamp.sec, self.header.stamp.nanosec, self.header.frame_id)
        writer.u32(self.height)
        writer.u32(self.width)
        writer.string(self.encoding)
        writer.u8(self.is_bigendian)
        writer.u32(self.step)
        writer.octets(_octet_buffer(self.data))
        return writer.getvalue()

    @classmethod
    def deserialize(cls, data, has_header=True, use_version_2=None):
        """From plain CDR through :class:`CdrReader` (``data`` as bytes); other forms: Cyclone's deserializer."""
        if not has_header or use_version_2 or bytes(data[:2]) not in (b"\x00\x00", b"\x00\x01"):
            return super().deserialize(data, has_header=has_header, use_version_2=use_version_2)
        reader = CdrReader(data)
        return cls(header=reader.header(), height=reader.u32(), width=reader.u32(), encoding=reader.string(),
                   is_bigendian=reader.u8(), step=reader.u32(), data=reader.octets())


@dataclass
class RegionOfInterest_(IdlStruct, typename="sensor_msgs::msg::dds_::RegionOfInterest_"):
    x_offset: uint32 = 0
    y_offset: uint32 = 0
    height: uint32 = 0
    width: uint32 = 0
    do_rectify: bool = False


@dataclass
class CameraInfo_(IdlStruct, typename="sensor_msgs::msg::dds_::CameraInfo_"):
    header: Header_ = field(default_factory=Header_)
    height: uint32 = 0
    width: uint32 = 0
    distortion_model: str = ""
    d: Float64s = field(default_factory=list)
    k: Float64x9 = field(default_factory=lambda: [0.0] * 9)
    r: Float64x9 = field(default_factory=lambda: [0.0] * 9)
    p: Float64x12 = field(default_factory=lambda: [0.0] * 12)
    binning_x: uint32 = 0
    binning_y: uint32 = 0
    roi: RegionOfInterest_ = field(default_factory=RegionOfInterest_)


@dataclass
class KeyValue_(IdlStruct, typename="diagnostic_msgs::msg::dds_::KeyValue_"):
    key: str = ""
    value: str = ""


@dataclass
class DiagnosticStatus_(IdlStruct, typename="diagnostic_msgs::msg::dds_::DiagnosticStatus_"):
    level: byte = 0  # ``byte`` in the .msg: IDL ``octet`` (rosidl_generator_dds_idl)
    name: str = ""
    message: str = ""
    hardware_id: str = ""
    values: Annotated[Sequence[KeyValue_], sequence(KeyValue_)] = field(default_factory=list)


@dataclass
class DiagnosticArray_(IdlStruct, typename="diagnostic_msgs::msg::dds_::DiagnosticArray_"):
    header: Header_ = field(default_factory=Header_)
    status: Annotated[Sequence[DiagnosticStatus_], sequence(DiagnosticStatus_)] = field(default_factory=list)


@dataclass
class Vector3_(IdlStruct, typename="geometry_msgs::msg::dds_::Vector3_"):
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0


@dataclass
class Quaternion_(IdlStruct, typename="geometry_msgs::msg::dds_::Quaternion_"):
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0
    w: float64 = 1.0


@dataclass
class Transform_(IdlStruct, typename="geometry_msgs::msg::dds_::Transform_"):
    translation: Vector3_ = field(default_factory=Vector3_)
    rotation: Quaternion_ = field(default_factory=Quaternion_)


@dataclass
class TransformStamped_(IdlStruct, typename="geometry_msgs::msg::dds_::TransformStamped_"):
    header: Header_ = field(default_factory=Header_)
    child_frame_id: str = ""
    transform: Transform_ = field(default_factory=Transform_)


@dataclass
class TFMessage_(IdlStruct, typename="tf2_msgs::msg::dds_::TFMessage_"):
    transforms: Annotated[Sequence[TransformStamped_], sequence(TransformStamped_)] = field(default_factory=list)


@dataclass
class Trigger_Request_(IdlStruct, typename="std_srvs::srv::dds_::Trigger_Request_"):
    """``std_srvs/srv/Trigger`` request as rmw_cyclonedds sends it: request header, then the (empty) request."""

    client_guid: uint64 = 0
    sequence_number: int64 = 0
    structure_needs_at_least_one_member: uint8 = 0


@dataclass
class Trigger_Response_(IdlStruct, typename="std_srvs::srv::dds_::Trigger_Response_"):
    """``std_srvs/srv/Trigger`` response with rmw_cyclonedds' header (the request's guid and sequence number)."""

    client_guid: uint64 = 0
    sequence_number: int64 = 0
    success: bool = False
    message: str = ""


_LITTLE = Endianness.Little
#: What :func:`to_dds` converts, for its errors.
_CARRIED = "sensor_msgs PointCloud2, Image, CameraInfo, diagnostic_msgs DiagnosticArray and tf2_msgs TFMessage"


def _octet_buffer(data):
    """A uint8 buffer of ``data`` (ndarray, bytes, memoryview or a list of ints)."""
    if isinstance(data, (bytes, bytearray, memoryview)):
        return data
    return np.ascontiguousarray(np.asarray(data, dtype=np.uint8))


def _as_library_sample(sample):
    """A copy of ``sample`` whose ``data`` is a list of ints, as Cyclone's own serializer wants it."""
    values = {name: getattr(sample, name) for name in sample.__dataclass_fields__}
    values["data"] = list(bytes(_octet_buffer(values["data"])))
    return type(sample)(**values)


def _header(msg) -> Header_:
    stamp = msg.header.stamp
    return Header_(stamp=Time_(sec=int(stamp.sec), nanosec=int(stamp.nanosec)), frame_id=msg.header.frame_id)


def to_dds(msg):
    """The ROS 2 DDS sample of one of our messages; ``data`` stays a view of the message's array (no copy).

    Parameters
    ----------
    msg : PointCloud2, Image, CameraInfo, DiagnosticArray or TFMessage
        A decoded ``dptpu.messages`` message.

    Returns
    -------
    PointCloud2_, Image_, CameraInfo_, DiagnosticArray_ or TFMessage_

    Raises
    ------
    ValueError
        For any other message type, naming it and the supported ones.
    """
    if isinstance(msg, PointCloud2):
        return PointCloud2_(
            header=_header(msg), height=int(msg.height), width=int(msg.width),
            fields=[PointField_(name=f.name, offset=int(f.offset), datatype=int(f.datatype), count=int(f.count))
                    for f in msg.fields],
            is_bigendian=bool(msg.is_bigendian), point_step=int(msg.point_step), row_step=int(msg.row_step),
            data=msg.data, is_dense=bool(msg.is_dense))
    if isinstance(msg, Image):
        return Image_(header=_header(msg), height=int(msg.height), width=int(msg.width), encoding=msg.encoding,
                      is_bigendian=int(msg.is_bigendian), step=int(msg.step), data=msg.data)
    if isinstance(msg, CameraInfo):
        roi = msg.roi
        return CameraInfo_(
            header=_header(msg), height=int(msg.height), width=int(msg.width),
            distortion_model=msg.distortion_model, d=[float(v) for v in np.asarray(msg.d, np.float64)],
            k=[float(v) for v in np.asarray(msg.k, np.float64)], r=[float(v) for v in np.asarray(msg.r, np.float64)],
            p=[float(v) for v in np.asarray(msg.p, np.float64)], binning_x=int(msg.binning_x),
            binning_y=int(msg.binning_y),
            roi=RegionOfInterest_(x_offset=int(roi.x_offset), y_offset=int(roi.y_offset), height=int(roi.height),
                                  width=int(roi.width), do_rectify=bool(roi.do_rectify)))
    if isinstance(msg, DiagnosticArray):
        return DiagnosticArray_(header=_header(msg), status=[
            DiagnosticStatus_(level=int(s.level), name=s.name, message=s.message, hardware_id=s.hardware_id,
                              values=[KeyValue_(key=v.key, value=v.value) for v in s.values])
            for s in msg.status])
    if isinstance(msg, TFMessage):
        return TFMessage_(transforms=[_transform_stamped(t) for t in msg.transforms])
    raise ValueError(f"the ROS 2 bridge carries {_CARRIED}; got {type(msg).__name__}")


def _transform_stamped(msg) -> TransformStamped_:
    t, q = msg.transform.translation, msg.transform.rotation
    return TransformStamped_(header=_header(msg), child_frame_id=msg.child_frame_id, transform=Transform_(
        translation=Vector3_(x=float(t.x), y=float(t.y), z=float(t.z)),
        rotation=Quaternion_(x=float(q.x), y=float(q.y), z=float(q.z), w=float(q.w))))


def dds_type_of(msg_type) -> type[IdlStruct]:
    """The IDL class of one of our message classes (``PointCloud2`` -> ``PointCloud2_``)."""
    types: dict[type, type[IdlStruct]] = {PointCloud2: PointCloud2_, Image: Image_, CameraInfo: CameraInfo_,
                                          DiagnosticArray: DiagnosticArray_, TFMessage: TFMessage_}
    if msg_type not in types:
        raise ValueError(f"the ROS 2 bridge carries {_CARRIED}; got {getattr(msg_type, '__name__', msg_type)}")
    return types[msg_type]


def ros_topic_name(topic: str, *, prefix: str = "rt") -> str:
    """DDS topic name of a ROS 2 topic: ``/scanner/points`` -> ``rt/scanner/points`` (``rq``/``rr``: services).

    Raises
    ------
    ValueError
        When ``topic`` is not an absolute ROS name.
    """
    if not topic.startswith("/") or topic == "/" or topic.endswith("/") or "//" in topic:
        raise ValueError(f"ROS 2 topic names for the bridge must be absolute, like /scanner/points; got {topic!r}")
    return f"{prefix}{topic}"
