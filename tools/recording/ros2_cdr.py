"""Our ROS types (``sensor_msgs/msg/Image``, ``CameraInfo``, ``PointCloud2`` ...) as ROS 2 ``.msg``
schemas and as the plain dicts mcap-ros2-support serializes to CDR, and back.

MCAP files written with these schemas (schema encoding ``ros2msg``, message encoding ``cdr``) open
in ROS 2 (``ros2 bag`` with the mcap storage plugin) and in Foxglove, because the bytes are exactly
what an rclpy publisher would have produced: same type names, field order and primitive types
(``docs/messages.md``, "Mapping to ROS 2").

- :func:`is_ros2_type`: which message classes travel as ROS 2 CDR (every registered type outside
  ``dptpu_msgs`` whose bulk arrays are 1-D, e.g. ``uint8[] data``).
- :func:`ros2_schema_text`: the concatenated ``.msg`` definition (main type, then ``=`` * 80 and
  ``MSG: package/Type`` blocks of the nested types), as ROS 2's rosbag2 writes it, plus the constants
  ROS 2 declares (``PointField.INT8 = 1`` ...).
- :func:`to_ros2_dict` / :func:`from_ros2`: message <-> nested dict of Python values, the form
  ``mcap_ros2.writer.Writer.write_message`` encodes and ``mcap_ros2.decoder.DecoderFactory`` decodes
  (it gives ``SimpleNamespace`` objects; dicts are accepted too).

The conversion is exact: integers, strings and booleans are copied, ``float64`` values keep their
bits, and ``uint8[]`` data is copied byte for byte, so ``from_ros2(cls, decode(encode(to_ros2_dict(m))))
== m`` bit-exactly.
"""

from __future__ import annotations

import numpy as np

from dptpu.messages.schema import ARRAY, MESSAGE, MESSAGE_LIST, SCALAR, SEQUENCE, Message, message_definition
from dptpu.messages.sensor import PointField

__all__ = ["SCANNER_PACKAGE", "is_ros2_type", "ros2_schema_text", "to_ros2_dict", "from_ros2"]

#: Package of the scanner's own types; they are recorded as ``dptpu-msgpack``, not as CDR.
SCANNER_PACKAGE = "dptpu_msgs"

# Constants ROS 2 declares in these definitions (the codec's schema has fields only). ``.msg``
# syntax: ``type NAME=value``.
_ROS2_CONSTANTS = {
    PointField: [f"uint8 {name}={getattr(PointField, name)}"
                 for name in ("INT8", "UINT8", "INT16", "UINT16", "INT32", "UINT32", "FLOAT32", "FLOAT64")],
}


def _is_message_class(cls) -> bool:
    return isinstance(cls, type) and issubclass(cls, Message) and hasattr(cls, "FIELDS")


def is_ros2_type(cls) -> bool:
    """True when instances of ``cls`` are recorded as ROS 2 CDR.

    That is every message class outside ``dptpu_msgs`` (the ROS 2 types ``sensor_msgs/...``,
    ``std_msgs/...``, ``builtin_interfaces/...``) whose bulk arrays, nested ones included, are 1-D:
    a ``.msg`` sequence has no shape, so a multi-dimensional array would not come back bit-exact.

    Parameters
    ----------
    cls : type
        A message class (made with :func:`dptpu.messages.schema.message`).
    """
    if not _is_message_class(cls):
        return False
    if cls.TYPE_NAME.split("/")[0] == SCANNER_PACKAGE:
        return False
    return _arrays_are_flat(cls, set())


def _arrays_are_flat(cls, seen: set) -> bool:
    if cls in seen:
        return True
    seen.add(cls)
    for spec in cls.FIELDS:
        if spec.kind == ARRAY and len(spec.axes) != 1:
            return False
        if spec.kind in (MESSAGE, MESSAGE_LIST) and not _arrays_are_flat(spec.message_type, seen):
            return False
    return True


def _check_ros2_type(cls) -> None:
    if not is_ros2_type(cls):
        name = getattr(cls, "TYPE_NAME", getattr(cls, "__name__", repr(cls)))
        raise ValueError(f"{name} is not recorded as ROS 2 CDR: expected a ROS message type outside "
                         f"{SCANNER_PACKAGE} with 1-D arrays only, such as sensor_msgs/msg/Image")


def ros2_schema_text(cls) -> str:
    """The ``ros2msg`` schema of ``cls``: its ``.msg`` definition and those of every type it nests.

    Parameters
    ----------
    cls : type
        A class for which :func:`is_ros2_type` is True, e.g. ``Image``.

    Returns
    -------
    str
        ``message_definition(cls)`` (the main definition, then ``=`` * 80, ``MSG: std_msgs/Header``
        and so on, depth-first, each type once) with ROS 2's constants added to their types
        (``uint8 INT8=1`` ... in ``sensor_msgs/PointField``). Nested type names use the
        ``package/Type`` form of ``.msg`` files, as rosbag2 writes them.

    Raises
    ------
    ValueError
        ``cls`` is a scanner type or has a multi-dimensional array.
    """
    _check_ros2_type(cls)
    text = message_definition(cls)
    for constant_owner, constants in _ROS2_CONSTANTS.items():
        block = _msg_block_header(constant_owner)
        if block in text:
            text = text.replace(block, block + "\n".join(constants) + "\n", 1)
        elif cls is constant_owner:
            text = "\n".join(constants) + "\n" + text
    return text


def _msg_block_header(cls) -> str:
    package, _, name = cls.TYPE_NAME.split("/")
    return f"MSG: {package}/{name}\n"


def to_ros2_dict(msg: Message) -> dict:
    """``msg`` as a nested dict of plain Python values, for mcap-ros2-support's CDR encoder.

    Parameters
    ----------
    msg : Message
        A message of a type for which :func:`is_ros2_type` is True; it must validate
        (``msg.validate()`` is run first, so a bad field raises the codec's ``EncodeError``).

    Returns
    -------
    dict
        ``{field: value}`` in schema order: scalars as ``int``/``float``/``bool``/``str``, inline
        sequences (``CameraInfo.k``) as lists, nested messages as dicts, ``uint8[]`` bulk arrays as
        ``bytes`` (one copy of the data), other 1-D arrays as lists.

    Raises
    ------
    ValueError
        A scanner type or a type with multi-dimensional arrays, or a message that does not validate.
    """
    if not isinstance(msg, Message):
        raise ValueError(f"msg must be a message such as sensor_msgs Image; got {type(msg).__name__}")
    _check_ros2_type(type(msg))
    msg.validate()
    return _fields_to_dict(msg)


def _fields_to_dict(msg: Message) -> dict:
    out = {}
    for spec in type(msg).FIELDS:
        value = getattr(msg, spec.name)
        if spec.kind == SCALAR:
            out[spec.name] = _plain_scalar(spec.primitive_name, value)
        elif spec.kind == SEQUENCE:
            out[spec.name] = np.asarray(value, spec.dtype).tolist()
        elif spec.kind == ARRAY:
            values = np.ascontiguousarray(value, spec.dtype)  # validated: already this dtype, 1-D
            out[spec.name] = values.tobytes() if spec.primitive == "uint8" else values.tolist()
        elif spec.kind == MESSAGE:
            out[spec.name] = _fields_to_dict(value)
        else:  # MESSAGE_LIST
            out[spec.name] = [_fields_to_dict(item) for item in value]
    return out


def _plain_scalar(primitive: str, value):
    if primitive == "string":
        return str(value)
    if primitive == "bool":
        return bool(value)
    if primitive == "float64":
        return float(value)
    return int(value)


def from_ros2(cls, decoded) -> Message:
    """A message of type ``cls`` from a decoded ROS 2 message (``SimpleNamespace`` tree or dict).

    Parameters
    ----------
    cls : type
        The message class, for which :func:`is_ros2_type` is True (e.g. ``PointCloud2``).
    decoded : object
        What ``mcap_ros2.decoder.DecoderFactory``'s decoder returns: attributes named as the fields
        (dict keys work too). ``uint8[]`` fields are bytes-like, other arrays lists of numbers.

    Returns
    -------
    Message
        Bulk ``uint8`` arrays are read-only views of the decoded bytes (as after the wire codec);
        inline sequences are new writable arrays. The message is validated.

    Raises
    ------
    ValueError
        A field is missing or has the wrong kind of value, or the message does not validate (e.g.
        ``len(Image.data) != step * height``); the error names the field.
    """
    _check_ros2_type(cls)
    msg = _message_from(cls, decoded, cls.__name__)
    msg.validate()
    return msg


def _field_value(decoded, name: str, where: str):
    if isinstance(decoded, dict):
        if name in decoded:
            return decoded[name]
    elif hasattr(decoded, name):
        return getattr(decoded, name)
    raise ValueError(f"{where}: the decoded ROS 2 message has no field {name!r}")


def _message_from(cls, decoded, where: str) -> Message:
    values = {}
    for spec in cls.FIELDS:
        raw = _field_value(decoded, spec.name, where)
        path = f"{where}.{spec.name}"
        if spec.kind == SCALAR:
            values[spec.name] = _scalar_from(spec.primitive, raw, path)
        elif spec.kind == SEQUENCE:
            values[spec.name] = _numbers_from(spec, raw, path).copy()
        elif spec.kind == ARRAY:
            values[spec.name] = _numbers_from(spec, raw, path)
        elif spec.kind == MESSAGE:
            values[spec.name] = _message_from(spec.message_type, raw, path)
        else:  # MESSAGE_LIST
            if not isinstance(raw, (list, tuple)):
                raise ValueError(f"{path} must be a list of {spec.message_type.__name__}; got {type(raw).__name__}")
            values[spec.name] = [_message_from(spec.message_type, item, f"{path}[{index}]")
                                 for index, item in enumerate(raw)]
    return cls(**values)


def _scalar_from(primitive: str, raw, path: str):
    if primitive == "string":
        ok = isinstance(raw, str)
    elif primitive == "bool":
        ok = isinstance(raw, (bool, np.bool_))
    elif primitive == "float64":
        ok = isinstance(raw, (float, int, np.floating, np.integer)) and not isinstance(raw, bool)
    else:
        ok = isinstance(raw, (int, np.integer)) and not isinstance(raw, (bool, np.bool_))
    if not ok:
        raise ValueError(f"{path} must be {primitive}; got {type(raw).__name__} {raw!r:.60}")
    return _plain_scalar(primitive, raw)


def _numbers_from(spec, raw, path: str) -> np.ndarray:
    dtype = spec.dtype
    if isinstance(raw, (bytes, bytearray, memoryview)):
        if dtype != np.uint8:
            raise ValueError(f"{path} must be a list of {spec.primitive}; got {type(raw).__name__}")
        values = np.frombuffer(raw, np.uint8)
        values.flags.writeable = False
        return values
    if not isinstance(raw, (list, tuple)):
        raise ValueError(f"{path} must be a sequence of {spec.primitive}; got {type(raw).__name__}")
    try:
        return np.array(raw, dtype=dtype).reshape(-1)
    except (TypeError, ValueError, OverflowError) as error:
        raise ValueError(f"{path} must hold {spec.primitive} values ({error})") from None
