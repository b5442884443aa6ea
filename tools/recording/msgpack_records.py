"""The ``dptpu-msgpack`` MCAP encoding of the scanner's own messages (``dptpu_msgs/msg/...``).

A scanner message is stored as the frames our wire codec (:mod:`dptpu.messages.encoder`) sends, so a
recording is bit-exact and the codec's strict checks guard the reading side too.

Schema record (one per type): ``encoding = "dptpu-msgpack"``, ``name`` = the type name
(``dptpu_msgs/msg/PhaseMaps``), ``data`` = one msgpack map::

    {"format": "dptpu-msgpack", "format_version": 1,
     "type": "dptpu_msgs/msg/PhaseMaps", "version": 1,      # the type's SCHEMA_VERSION
     "wire": 1,                                             # the codec's wire format version
     "definition": "std_msgs/Header header\\n..."}           # message_definition(cls): fields, axes

Message record: channel ``message_encoding = "dptpu-msgpack"``, ``data`` = one msgpack array of bin
items, the codec frames without the topic (the channel holds the topic)::

    [header_bytes, array_0_bytes, array_1_bytes, ...]

``header_bytes`` is the codec's msgpack header (type, version, scalar fields, array descriptors) and
``array_i_bytes`` the raw little-endian C-order bytes of bulk array ``i``. Reading prepends the
channel's topic and runs :func:`dptpu.messages.decode` with the channel's type, so every limit,
dtype and shape check of the wire applies.
"""

from __future__ import annotations

import msgpack

from dptpu.messages import DEFAULT_LIMITS, DecodeError, DecodeLimits, decode, encode, lookup
from dptpu.messages.schema import Message, message_definition
from dptpu.messages.wire_format import WIRE_VERSION

__all__ = ["ENCODING", "FORMAT_VERSION", "schema_data", "parse_schema_data", "pack_message", "unpack_message"]

#: Schema and message encoding name in the MCAP file.
ENCODING = "dptpu-msgpack"
#: Version of this record layout (the schema map and the list-of-frames packing).
FORMAT_VERSION = 1

_SCHEMA_KEYS = ("format", "format_version", "type", "version", "wire", "definition")
_MAX_SCHEMA_BYTES = 1 << 20


def schema_data(cls) -> bytes:
    """The schema record's data for message class ``cls``: the msgpack map of the module docstring.

    Parameters
    ----------
    cls : type
        A registered message class, e.g. ``PhaseMaps``.
    """
    if not (isinstance(cls, type) and issubclass(cls, Message) and hasattr(cls, "FIELDS")):
        raise ValueError(f"cls must be a message class; got {cls!r}")
    return msgpack.packb({"format": ENCODING, "format_version": FORMAT_VERSION, "type": cls.TYPE_NAME,
                          "version": cls.SCHEMA_VERSION, "wire": WIRE_VERSION,
                          "definition": message_definition(cls)}, use_bin_type=True)


def parse_schema_data(name: str, data: bytes) -> type:
    """The message class of a ``dptpu-msgpack`` schema record, checked against this build.

    Parameters
    ----------
    name : str
        The schema record's name (the type name).
    data : bytes
        The schema record's data.

    Returns
    -------
    type
        The registered class named ``name``.

    Raises
    ------
    ValueError
        Malformed schema data, a type unknown to this build, or a different schema, wire or record
        format version (the message gives both versions).
    """
    if len(data) > _MAX_SCHEMA_BYTES:
        raise ValueError(f"dptpu-msgpack schema {name!r} has {len(data)} bytes > {_MAX_SCHEMA_BYTES}")
    try:
        schema = msgpack.unpackb(data, raw=False, strict_map_key=True)
    except (ValueError, TypeError, msgpack.UnpackException) as error:
        raise ValueError(f"dptpu-msgpack schema {name!r} is not valid msgpack ({error})") from None
    if type(schema) is not dict or sorted(schema) != sorted(_SCHEMA_KEYS):
        keys = sorted(schema) if type(schema) is dict else type(schema).__name__
        raise ValueError(f"dptpu-msgpack schema {name!r} must be a map with keys {', '.join(_SCHEMA_KEYS)}; "
                         f"got {keys}")
    if schema["format"] != ENCODING or schema["format_version"] != FORMAT_VERSION:
        raise ValueError(f"dptpu-msgpack schema {name!r} has format {schema['format']!r} version "
                         f"{schema['format_version']!r}; this build reads {ENCODING!r} version {FORMAT_VERSION}")
    if schema["type"] != name:
        raise ValueError(f"dptpu-msgpack schema named {name!r} describes type {schema['type']!r}")
    try:
        cls = lookup(name)
    except KeyError as error:
        raise ValueError(f"dptpu-msgpack schema: {error.args[0]}") from None
    if schema["version"] != cls.SCHEMA_VERSION:
        raise ValueError(f"schema version mismatch for {name}: the file has version {schema['version']!r}, "
                         f"this build has {cls.SCHEMA_VERSION}")
    if schema["wire"] != WIRE_VERSION:
        raise ValueError(f"wire format version mismatch for {name}: the file has {schema['wire']!r}, "
                         f"this build has {WIRE_VERSION}")
    return cls


def pack_message(msg: Message) -> bytes:
    """The message record's data for ``msg``: a msgpack array ``[header, *array_bytes]``.

    Raises
    ------
    EncodeError
        A field of the wrong type, dtype, shape or range (the codec's checks).
    """
    frames = encode("/record", msg)  # the topic frame is dropped: the channel holds the topic
    return msgpack.packb(frames[1:], use_bin_type=True)


def unpack_message(topic: str, data: bytes, cls: type, *, limits: DecodeLimits = DEFAULT_LIMITS) -> Message:
    """Decode a message record's data written by :func:`pack_message`.

    Parameters
    ----------
    topic : str
        The channel's topic (for error messages and the codec's topic frame).
    data : bytes
        The record's data.
    cls : type
        The channel's message class (from :func:`parse_schema_data`); another type is refused.
    limits : DecodeLimits
        The codec's limits (frames, bytes, dimensions).

    Returns
    -------
    Message
        Bulk arrays are read-only views of the record's bytes.

    Raises
    ------
    DecodeError
        Not a msgpack array of bin items, too large, or any problem the wire codec finds.
    """
    if len(data) > limits.max_total_bytes + 64 * limits.max_frames:
        raise DecodeError(f"record on topic {topic!r} has {len(data)} bytes > max_total_bytes "
                          f"{limits.max_total_bytes}")
    try:
        frames = msgpack.unpackb(data, raw=False, use_list=True, max_array_len=limits.max_frames,
                                 max_map_len=0, max_str_len=0, max_ext_len=0)
    except (ValueError, TypeError, msgpack.UnpackException) as error:
        raise DecodeError(f"record on topic {topic!r} is not a msgpack array of frames "
                          f"({type(error).__name__}: {error})") from None
    if type(frames) is not list or not frames or not all(type(frame) is bytes for frame in frames):
        raise DecodeError(f"record on topic {topic!r} must be a non-empty msgpack array of bin items")
    _, msg = decode([topic.encode("utf-8"), *frames], expected_type=cls, limits=limits)
    return msg
