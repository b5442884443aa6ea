"""Every message type in ROS 2's CDR (XCDR1, little-endian), the bytes an rclpy publisher sends: encode and decode.

The layout is the type's ROS 2 form (:mod:`.ros2_definitions`: the scanner types' multi-dimensional arrays flat,
with ``height`` and ``width``), serialized as ``rmw_cyclonedds`` and rosbag2 do: a 4-byte encapsulation header
``00 01 00 00``, then the fields in order, each primitive aligned to its size from the start of the body, strings
as ``uint32`` length (NUL included) + bytes + NUL, sequences as ``uint32`` count + elements, fixed arrays as their
elements, nested messages inline.

Arrays are written and read as whole numpy buffers (one copy each way), so a 640 x 480 scan's maps go through in
milliseconds, where a per-element encoder (mcap-ros2-support's) takes seconds. :func:`decode_cdr` gives arrays as
read-only views of the input and validates the message (the codec's checks), so a record that does not fit its type
is a ``ValueError`` naming the field.
"""

from __future__ import annotations

import struct

import numpy as np

from .field_spec import ARRAY, ARRAY_DTYPES, MESSAGE, SCALAR, SEQUENCE
from .ros2_definitions import SHAPE_FIELDS, Ros2Field, ros2_fields
from .schema import Message

__all__ = ["CDR_LE_HEADER", "decode_cdr", "encode_cdr"]

#: Encapsulation header of plain CDR, little-endian (RTPS ``CDR_LE``).
CDR_LE_HEADER = b"\x00\x01\x00\x00"
_FORMATS = {"bool": "?", "int8": "b", "uint8": "B", "int16": "h", "uint16": "H", "int32": "i", "uint32": "I",
            "int64": "q", "uint64": "Q", "float32": "f", "float64": "d"}


def encode_cdr(msg: Message) -> bytes:
    """The CDR bytes (encapsulation header included) of ``msg`` in its ROS 2 form.

    Raises
    ------
    ValueError
        The message does not validate (the codec's checks run first).
    """
    if not isinstance(msg, Message):
        raise ValueError(f"msg must be a message; got {type(msg).__name__}")
    msg.validate()
    writer = _Writer()
    _encode(writer, msg)
    return writer.getvalue()


def decode_cdr(cls: type[Message], data) -> Message:
    """The message of type ``cls`` in CDR ``data`` (bytes-like, encapsulation header included).

    Raises
    ------
    ValueError
        Not little-endian plain CDR, too short or too long for the type, or a message that does not validate; the
        message names the field.
    """
    view = memoryview(data).cast("B")
    if bytes(view[:4]) not in (CDR_LE_HEADER, b"\x00\x01\x00\x01"):
        raise ValueError(f"{cls.__name__}: not little-endian plain CDR (encapsulation {bytes(view[:4]).hex()}; "
                         f"expected {CDR_LE_HEADER.hex()})")
    reader = _Reader(view[4:])
    msg = _decode(reader, cls, cls.__name__)
    if reader.offset != len(reader.data) and len(reader.data) - reader.offset >= 4:
        raise ValueError(f"{cls.__name__}: {len(reader.data) - reader.offset} bytes left after the message")
    msg.validate()
    return msg


# -- encoding -------------------------------------------------------------------------------------------------

class _Writer:
    def __init__(self) -> None:
        self.parts: list = [CDR_LE_HEADER]
        self.head = bytearray()
        self.offset = 0

    def align(self, size: int) -> None:
        pad = -self.offset % size
        if pad:
            self.head += b"\x00" * pad
            self.offset += pad

    def scalar(self, primitive: str, value) -> None:
        if primitive == "string":
            raw = str(value).encode("utf-8") + b"\x00"
            self.scalar("uint32", len(raw))
            self.head += raw
            self.offset += len(raw)
            return
        size = ARRAY_DTYPES[primitive].itemsize
        self.align(size)
        self.head += struct.pack("<" + _FORMATS[primitive], value)
        self.offset += size

    def array(self, values: np.ndarray, *, counted: bool) -> None:
        if counted:
            self.scalar("uint32", values.size)
        if values.size:
            self.align(values.dtype.itemsize)
            self.parts.append(bytes(self.head))
            self.head = bytearray()
            self.parts.append(np.ascontiguousarray(values).data.cast("B"))
            self.offset += values.nbytes

    def getvalue(self) -> bytes:
        return b"".join([*self.parts, bytes(self.head)])


def _encode(writer: _Writer, msg: Message) -> None:
    fields = ros2_fields(type(msg))
    sizes = _sizes(msg, fields)
    for field in fields:
        spec = field.spec
        if spec is None:
            writer.scalar("uint32", sizes[field.name])
            continue
        value = getattr(msg, spec.name)
        if spec.kind == SCALAR:
            writer.scalar(spec.primitive_name, value)
        elif spec.kind == SEQUENCE:
            values = np.asarray(value, dtype=spec.element_dtype).reshape(-1)
            writer.array(values, counted=spec.length is None)
        elif spec.kind == ARRAY:
            writer.array(np.asarray(value, dtype=spec.element_dtype).reshape(-1), counted=True)
        elif spec.kind == MESSAGE:
            _encode(writer, value)
        else:  # MESSAGE_LIST
            writer.scalar("uint32", len(value))
            for item in value:
                _encode(writer, item)


def _sizes(msg: Message, fields: tuple[Ros2Field, ...]) -> dict[str, int]:
    """``height`` and ``width`` of a scanner type's flattened arrays (0 when it has none: no array)."""
    sizes = {name: 0 for name in SHAPE_FIELDS.values()}
    for field in fields:
        if field.shape and field.spec is not None:
            shape = np.shape(getattr(msg, field.spec.name))
            for axis, extent in zip(field.shape, shape):
                if axis in sizes:
                    sizes[axis] = int(extent)
            break
    return sizes


# -- decoding -------------------------------------------------------------------------------------------------

class _Reader:
    def __init__(self, data: memoryview):
        self.data = data
        self.offset = 0

    def align(self, size: int) -> None:
        self.offset += -self.offset % size

    def take(self, count: int, where: str) -> memoryview:
        end = self.offset + count
        if count < 0 or end > len(self.data):
            raise ValueError(f"{where}: the record ends after {len(self.data)} bytes; {count} more were needed at "
                             f"byte {self.offset}")
        chunk = self.data[self.offset:end]
        self.offset = end
        return chunk

    def scalar(self, primitive: str, where: str):
        if primitive == "string":
            length = self.scalar("uint32", where)
            raw = bytes(self.take(length, where))
            if not raw.endswith(b"\x00"):
                raise ValueError(f"{where}: a CDR string must end with NUL")
            return raw[:-1].decode("utf-8")
        size = ARRAY_DTYPES[primitive].itemsize
        self.align(size)
        return struct.unpack("<" + _FORMATS[primitive], self.take(size, where))[0]

    def array(self, primitive: str, count: int, where: str) -> np.ndarray:
        dtype = ARRAY_DTYPES[primitive]
        if count:
            self.align(dtype.itemsize)
        values = np.frombuffer(self.take(count * dtype.itemsize, where), dtype=dtype)
        values.flags.writeable = False
        return values


def _decode(reader: _Reader, cls: type[Message], where: str) -> Message:
    values: dict = {}
    sizes: dict[str, int] = {}
    for field in ros2_fields(cls):
        path = f"{where}.{field.name}"
        spec = field.spec
        if spec is None:
            sizes[field.name] = reader.scalar("uint32", path)
        elif spec.kind == SCALAR:
            values[spec.name] = reader.scalar(spec.primitive_name, path)
        elif spec.kind == SEQUENCE:
            count = spec.length if spec.length is not None else reader.scalar("uint32", path)
            values[spec.name] = reader.array(spec.primitive_name, count, path).copy()
        elif spec.kind == ARRAY:
            flat = reader.array(spec.primitive_name, reader.scalar("uint32", path), path)
            values[spec.name] = _shaped(flat, field, sizes, path)
        elif spec.kind == MESSAGE:
            values[spec.name] = _decode(reader, spec.nested_type, path)
        else:  # MESSAGE_LIST
            count = reader.scalar("uint32", path)
            values[spec.name] = [_decode(reader, spec.nested_type, f"{path}[{i}]") for i in range(count)]
    return cls(**values)


def _shaped(flat: np.ndarray, field: Ros2Field, sizes: dict[str, int], path: str) -> np.ndarray:
    """A flattened array back in its axes: ``height`` and ``width`` from the fields, one other axis from the
    length."""
    if not field.shape:
        return flat
    known = int(np.prod([sizes[axis] for axis in field.shape if axis in sizes]))
    shape = []
    for axis in field.shape:
        if axis in sizes:
            shape.append(sizes[axis])
        elif known == 0:  # empty planes: only an empty array fits, and its other axis is lost in the flattening
            if flat.size:
                raise ValueError(f"{path}: {flat.size} elements in planes of 0 (height x width) elements")
            shape.append(0)
        elif flat.size % known:
            raise ValueError(f"{path}: {flat.size} elements are not a whole number of {known}-element "
                             f"(height x width) planes")
        else:
            shape.append(flat.size // known)
    if int(np.prod(shape)) != flat.size:
        raise ValueError(f"{path}: {flat.size} elements do not fill the shape {tuple(shape)}")
    return flat.reshape(shape)
