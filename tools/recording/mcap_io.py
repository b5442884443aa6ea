"""Write and read MCAP recordings of our messages (no graph needed).

One MCAP channel per topic; a topic carries one message type. Every channel is ROS 2 CDR (``docs/recording.md``):
schema encoding ``ros2msg`` (the type's ROS 2 form, :func:`dptpu.messages.ros2_definitions.ros2_message_definition`:
the ROS types as ROS 2 defines them, the scanner's ``dptpu_msgs`` types as their shipped ``.msg`` files), message
encoding ``cdr`` (:func:`dptpu.messages.cdr.encode_cdr`), and channel metadata ``offered_qos_profiles``
(:mod:`.offered_qos`), so ``ros2 bag`` and Foxglove read the whole file. Files of earlier builds, whose scanner
channels are ``dptpu-msgpack`` (:mod:`.msgpack_records`), are still read.

Messages round-trip bit-exactly: ``read_mcap`` gives back messages equal (``==``, arrays bit for bit) to
those written. Times are integer nanoseconds since the Unix epoch.

Example::

    with McapRecordWriter("scan.mcap") as writer:
        writer.write("/camera/image_raw", image, log_time_ns=time.time_ns())
    for topic, msg, log_time_ns in read_mcap("scan.mcap"):
        ...
"""

from __future__ import annotations

import os
import threading
from collections import Counter
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import IO, NamedTuple

from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.well_known import MessageEncoding, SchemaEncoding
from mcap.writer import LIBRARY_IDENTIFIER as MCAP_LIBRARY_IDENTIFIER
from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter
from mcap_ros2.decoder import DecoderFactory

from dptpu.messages import DEFAULT_LIMITS, DecodeLimits, lookup
from dptpu.messages.cdr import decode_cdr, encode_cdr
from dptpu.messages.ros2_definitions import ros2_message_definition
from dptpu.messages.schema import Message

from . import msgpack_records
from .mcap_integrity import PARSE_ERRORS, check_summary_crc, find_corruption
from .mcap_integrity import reason as _reason
from .offered_qos import DEFAULT_OFFERED_QOS, offered_qos_profiles
from .ros2_cdr import from_ros2, is_ros2_type

__all__ = ["McapRecordWriter", "RecordedMessage", "ChannelSummary", "McapReadError", "read_mcap", "describe_mcap",
           "read_metadata", "verify_mcap", "COMPRESSIONS"]

#: Chunk compressions a writer accepts.
COMPRESSIONS = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "none": CompressionType.NONE}
_UINT64_MAX = 2**64 - 1
#: What reading a damaged or foreign file can raise (the mcap library's parsers, decompressors, the file itself).
_READ_ERRORS: tuple[type[BaseException], ...] = (*PARSE_ERRORS, OSError)
#: What turning a record's bytes into a message can raise.
_DECODE_ERRORS: tuple[type[BaseException], ...] = (*PARSE_ERRORS, NotImplementedError, IndexError, TypeError)
#: The Header record's library field.
_LIBRARY = f"{MCAP_LIBRARY_IDENTIFIER} dptpu"
#: Channel metadata key of the offered QoS (rosbag2's).
OFFERED_QOS_KEY = "offered_qos_profiles"


class McapReadError(ValueError):
    """An MCAP file cannot be read into our messages: not MCAP, truncated, an unknown type or encoding,
    another schema version, or a malformed message (the message names the file, topic and time)."""


class RecordedMessage(NamedTuple):
    """One message of a recording, as :func:`read_mcap` yields it.

    Attributes
    ----------
    topic : str
        The channel's topic, e.g. ``"/camera/image_raw"``.
    message : Message
        The decoded message (bulk arrays are read-only).
    log_time_ns : int
        When the recorder received it, ns since the Unix epoch.
    """

    topic: str
    message: Message
    log_time_ns: int


@dataclass(frozen=True)
class ChannelSummary:
    """One channel of an MCAP file (:func:`describe_mcap`).

    Attributes
    ----------
    topic : str
    type_name : str
        The schema name, e.g. ``"sensor_msgs/msg/Image"`` ("" for a schema-less channel).
    message_encoding : str
        ``"cdr"``, ``"dptpu-msgpack"`` or whatever another writer used.
    schema_encoding : str
        ``"ros2msg"``, ``"dptpu-msgpack"``, ...
    message_count : int
    readable : bool
        True when :func:`read_mcap` can turn the channel's messages into our message types.
    """

    topic: str
    type_name: str
    message_encoding: str
    schema_encoding: str
    message_count: int
    readable: bool


# --------------------------------------------------------------------------------------------------
# Writing
# --------------------------------------------------------------------------------------------------

@dataclass
class _Channel:
    cls: type[Message]
    channel_id: int
    count: int = 0


class McapRecordWriter:
    """Writes messages to an MCAP file, every channel ROS 2 CDR with a ``ros2msg`` schema.

    Parameters
    ----------
    output : str, os.PathLike or binary file object
        Path of the ``.mcap`` file to create (overwritten), or a writable binary stream (left open
        by :meth:`close`).
    compression : {"zstd", "lz4", "none"}
        Chunk compression (zstd is what ``ros2 bag record --storage mcap`` uses by default).
    chunk_size_bytes : int
        Uncompressed bytes collected before a chunk is compressed and written (> 0).

    Notes
    -----
    The file starts with the ``ros2`` profile header: every channel is ``cdr`` with a ``ros2msg`` schema and
    ``offered_qos_profiles`` metadata (:meth:`offer_qos`; ROS 2's default profile otherwise), a ROS 2 bag.
    :meth:`close` writes the summary (schemas, channels, statistics, chunk indexes); a file that was never
    closed lacks it (``mcap recover`` repairs it). :meth:`write` is thread-safe.
    """

    def __init__(self, output, *, compression: str = "zstd", chunk_size_bytes: int = 1 << 20):
        if compression not in COMPRESSIONS:
            raise ValueError(f"compression must be one of {', '.join(COMPRESSIONS)}; got {compression!r}")
        if isinstance(chunk_size_bytes, bool) or not isinstance(chunk_size_bytes, int) or chunk_size_bytes < 1:
            raise ValueError(f"chunk_size_bytes must be a positive int; got {chunk_size_bytes!r}")
        if isinstance(output, (str, os.PathLike)):
            self._stream: IO[bytes] = open(output, "wb")
            self._owns_stream = True
        elif hasattr(output, "write"):
            self._stream = output
            self._owns_stream = False
        else:
            raise ValueError(f"output must be a path or a writable binary file; got {type(output).__name__}")
        # Chunk CRCs and the data section CRC on (mcap-ros2-support's writer leaves the latter off and has no
        # argument for it), so a reader finds flipped bytes anywhere before the summary (mcap_integrity).
        self._mcap = McapWriter(self._stream, chunk_size=chunk_size_bytes, compression=COMPRESSIONS[compression],
                                enable_crcs=True, enable_data_crcs=True)
        self._mcap.start(profile="ros2", library=_LIBRARY)
        self._channels: dict[str, _Channel] = {}
        self._schema_ids: dict[type[Message], int] = {}
        self._offered_qos: dict[str, str] = {}  # topic -> offered_qos_profiles YAML
        self._lock = threading.Lock()
        self._closed = False

    # -- public API ------------------------------------------------------------------------------

    def write(self, topic: str, msg: Message, log_time_ns: int, *, publish_time_ns: int | None = None) -> None:
        """Append ``msg`` on ``topic``.

        Parameters
        ----------
        topic : str
            Non-empty topic name; the first message on a topic fixes its type.
        msg : Message
            A registered message; it must validate (the codec's checks).
        log_time_ns : int
            When the message was received, ns since the Unix epoch (>= 0).
        publish_time_ns : int, optional
            When it was published (default: ``log_time_ns``).

        Raises
        ------
        ValueError
            A bad topic or time, a message of another type than the topic's first one, a message that
            does not validate, or a closed writer.
        """
        if not isinstance(topic, str) or not topic:
            raise ValueError(f"topic must be a non-empty str; got {topic!r}")
        log_time_ns = _check_time("log_time_ns", log_time_ns)
        publish_time_ns = log_time_ns if publish_time_ns is None else _check_time("publish_time_ns",
                                                                                  publish_time_ns)
        if not isinstance(msg, Message) or not hasattr(type(msg), "TYPE_NAME"):
            raise ValueError(f"msg must be a message (e.g. sensor_msgs Image); got {type(msg).__name__}")
        cls = type(msg)
        payload = encode_cdr(msg)  # checks first
        with self._lock:
            if self._closed:
                raise ValueError("cannot write: the MCAP writer is closed")
            channel = self._channel(topic, cls)
            self._mcap.add_message(channel_id=channel.channel_id, log_time=log_time_ns, data=payload,
                                   publish_time=publish_time_ns, sequence=channel.count % 2**32)
            channel.count += 1

    def offer_qos(self, topic: str, profile: dict) -> None:
        """Record ``profile`` (``QoSProfile.to_dict()``) as ``topic``'s ``offered_qos_profiles``; before the
        topic's first message (a later call has no effect on a channel already written)."""
        yaml = offered_qos_profiles(profile)  # checks first
        with self._lock:
            self._offered_qos[topic] = yaml

    @property
    def message_counts(self) -> dict[str, int]:
        """Messages written so far, ``{topic: count}``, in the order the topics first appeared."""
        with self._lock:
            return {topic: channel.count for topic, channel in self._channels.items()}

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        """Write an MCAP metadata record ``name`` with string key-value pairs (e.g. the command line)."""
        if not isinstance(name, str) or not isinstance(data, dict) or not all(
                isinstance(k, str) and isinstance(v, str) for k, v in data.items()):
            raise ValueError("metadata must be a name (str) and a dict of str to str")
        with self._lock:
            if self._closed:
                raise ValueError("cannot write: the MCAP writer is closed")
            self._mcap.add_metadata(name, data)

    def close(self) -> None:
        """Write the summary and close the file (a stream given by the caller is flushed, not closed).

        Calling it again does nothing.
        """
        with self._lock:
            if self._closed:
                return
            self._closed = True
            try:
                self._mcap.finish()
            finally:
                if self._owns_stream:
                    self._stream.close()
                else:
                    self._stream.flush()

    @property
    def closed(self) -> bool:
        """True once :meth:`close` ran."""
        return self._closed

    def __enter__(self) -> McapRecordWriter:
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()

    # -- channels --------------------------------------------------------------------------------

    def _channel(self, topic: str, cls: type[Message]) -> _Channel:
        channel = self._channels.get(topic)
        if channel is not None:
            if channel.cls is not cls:
                raise ValueError(f"topic {topic!r} is recorded as {channel.cls.TYPE_NAME}; got a {cls.TYPE_NAME}")
            return channel
        schema_id = self._schema_ids.get(cls)
        if schema_id is None:
            schema_id = self._schema_ids[cls] = self._mcap.register_schema(
                name=cls.TYPE_NAME, encoding=SchemaEncoding.ROS2, data=ros2_message_definition(cls).encode())
        qos = self._offered_qos.get(topic) or offered_qos_profiles(DEFAULT_OFFERED_QOS)
        channel = self._channels[topic] = _Channel(cls, self._mcap.register_channel(
            topic=topic, message_encoding=MessageEncoding.CDR, schema_id=schema_id, metadata={OFFERED_QOS_KEY: qos}))
        return channel


def _check_time(name: str, value) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= _UINT64_MAX:
        raise ValueError(f"{name} must be an int of nanoseconds in [0, 2**64); got {value!r}")
    return value


# --------------------------------------------------------------------------------------------------
# Reading
# --------------------------------------------------------------------------------------------------

def read_mcap(path, *, topics: Iterable[str] | None = None, skip_unknown: bool = False,
              limits: DecodeLimits = DEFAULT_LIMITS, verify: bool = True) -> Iterator[RecordedMessage]:
    """Yield the messages of an MCAP file in log-time order as our message types.

    Parameters
    ----------
    path : str or os.PathLike
        The ``.mcap`` file: written by :class:`McapRecordWriter`, ``ros2 bag record`` or any writer
        using ROS 2 CDR with ``ros2msg`` schemas of types we have.
    topics : iterable of str, optional
        Only these topics (default: all).
    skip_unknown : bool
        Skip channels we cannot decode (a type we do not have, another encoding) instead of raising.
    limits : DecodeLimits
        Limits for ``dptpu-msgpack`` records (those of the wire codec by default).
    verify : bool
        Check every CRC of the file (chunks, data section, summary: :func:`.mcap_integrity.find_corruption`)
        before the first message. Without it the chunk CRCs are still checked as chunks are read.

    Yields
    ------
    RecordedMessage
        ``(topic, message, log_time_ns)``.

    Raises
    ------
    FileNotFoundError
        No such file.
    McapReadError
        Not an MCAP file, truncated, corrupt (a CRC that does not match: the message names the byte
        offset), an undecodable channel (unless ``skip_unknown``), a schema of another version, or a
        malformed message; the message names the topic and log time.
    """
    path = _existing_path(path)
    topic_filter = None if topics is None else _topic_list(topics)
    if verify:
        verify_mcap(path)
    converters: dict[int, _Converter | None] = {}  # channel id -> its converter, None for an undecodable one
    ros2_decoders = DecoderFactory()
    with open(path, "rb") as stream:
        reader = _open_reader(path, stream, validate_crcs=True)
        iterator = reader.iter_messages(topics=topic_filter, log_time_order=True)
        while True:
            try:
                item = next(iterator)
            except StopIteration:
                return
            except _READ_ERRORS as error:
                problem = find_corruption(path)
                if problem is not None:
                    raise McapReadError(f"cannot read {path}: corrupt: {problem}") from None
                raise McapReadError(f"cannot read {path}: {_reason(error)} (a recording that was not closed lacks "
                                    "its summary; `mcap recover` repairs it)") from None
            schema, channel, record = item
            if channel.id not in converters:
                converters[channel.id] = _converter(path, schema, channel, ros2_decoders, limits)
            converter = converters[channel.id]
            if converter is None:
                if skip_unknown:
                    continue
                raise McapReadError(f"cannot read {path}: {_undecodable_reason(schema, channel)}; pass "
                                    "skip_unknown=True or choose topics")
            try:
                msg = converter(record.data)
            except _DECODE_ERRORS as error:
                raise McapReadError(f"cannot read {path}: message on {channel.topic!r} at log time "
                                    f"{record.log_time} ns: {error}") from None
            yield RecordedMessage(channel.topic, msg, record.log_time)


def describe_mcap(path) -> list[ChannelSummary]:
    """The channels of an MCAP file with their types, encodings and message counts, by topic.

    Uses the file's summary (statistics) when present; otherwise counts by reading every message.

    Raises
    ------
    FileNotFoundError
        No such file.
    McapReadError
        Not an MCAP file, or its summary section does not match its CRC.
    """
    path = _existing_path(path)
    _check_summary(path)
    with open(path, "rb") as stream:
        reader = _open_reader(path, stream)
        try:
            summary = reader.get_summary()
            if summary is not None and summary.statistics is not None:
                counts = dict(summary.statistics.channel_message_counts)
                channels, schemas = summary.channels, summary.schemas
            else:  # no summary: a linear scan
                counts, channels, schemas = Counter(), {}, {}
                for schema, channel, _ in reader.iter_messages(log_time_order=False):
                    counts[channel.id] += 1
                    channels[channel.id] = channel
                    if schema is not None:
                        schemas[schema.id] = schema
        except _READ_ERRORS as error:
            raise McapReadError(f"cannot read {path}: {_reason(error)}") from None
    out = []
    for channel_id, channel in channels.items():
        schema = schemas.get(channel.schema_id)
        out.append(ChannelSummary(topic=channel.topic, type_name=schema.name if schema else "",
                                  message_encoding=channel.message_encoding,
                                  schema_encoding=schema.encoding if schema else "",
                                  message_count=int(counts.get(channel_id, 0)),
                                  readable=_readable_reason(schema, channel) is None))
    return sorted(out, key=lambda summary: summary.topic)


def read_metadata(path) -> dict[str, dict[str, str]]:
    """The metadata records of an MCAP file, ``{name: {key: value}}`` (a later record of the same name
    updates an earlier one).

    Raises
    ------
    FileNotFoundError
        No such file.
    McapReadError
        Not an MCAP file, or unreadable (a summary section that does not match its CRC included).
    """
    path = _existing_path(path)
    _check_summary(path)
    out: dict[str, dict[str, str]] = {}
    with open(path, "rb") as stream:
        reader = _open_reader(path, stream)
        try:
            for record in reader.iter_metadata():
                out.setdefault(record.name, {}).update(record.metadata)
        except _READ_ERRORS as error:
            raise McapReadError(f"cannot read {path}: {_reason(error)}") from None
    return out


def verify_mcap(path) -> None:
    """Check every CRC and the framing of an MCAP file (one pass, every chunk decompressed).

    Raises
    ------
    FileNotFoundError
        No such file.
    McapReadError
        Not an MCAP file, or damaged: the message names the byte offset of the record at fault and the CRC
        or parse error (:func:`.mcap_integrity.find_corruption`).
    """
    path = _existing_path(path)
    with open(path, "rb") as stream:
        _open_reader(path, stream)  # "not an MCAP file" before any CRC talk
    try:
        problem = find_corruption(path)
    except OSError as error:
        raise McapReadError(f"cannot read {path}: {_reason(error)}") from None
    if problem is not None:
        raise McapReadError(f"cannot read {path}: corrupt: {problem}")


def _check_summary(path: Path) -> None:
    with open(path, "rb") as stream:
        _open_reader(path, stream)
    problem = check_summary_crc(path)
    if problem is not None:
        raise McapReadError(f"cannot read {path}: corrupt: {problem}")


#: Turns one record's bytes into a message.
_Converter = Callable[[bytes], Message]


def _existing_path(path) -> Path:
    if not isinstance(path, (str, os.PathLike)):
        raise ValueError(f"path must be a str or os.PathLike; got {type(path).__name__}")
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no MCAP file at {path}")
    return path


def _topic_list(topics) -> list[str]:
    if isinstance(topics, str):
        return [topics]
    topics = list(topics)
    if not all(isinstance(topic, str) and topic for topic in topics):
        raise ValueError(f"topics must be non-empty strings; got {topics!r}")
    return topics


def _open_reader(path: Path, stream, *, validate_crcs: bool = False):
    try:
        return make_reader(stream, validate_crcs=validate_crcs)
    except _READ_ERRORS as error:
        raise McapReadError(f"cannot read {path}: not an MCAP file ({_reason(error)})") from None


def _readable_reason(schema, channel) -> str | None:
    """None when we can decode the channel, else why not."""
    if schema is None:
        return f"topic {channel.topic!r} has no schema"
    encodings = (schema.encoding, channel.message_encoding)
    if encodings == (msgpack_records.ENCODING, msgpack_records.ENCODING):
        return None
    if encodings != (SchemaEncoding.ROS2, MessageEncoding.CDR):
        return (f"topic {channel.topic!r} has schema encoding {schema.encoding!r} and message encoding "
                f"{channel.message_encoding!r}; readable are ros2msg/cdr and dptpu-msgpack")
    try:
        cls = lookup(schema.name)
    except KeyError:
        return f"topic {channel.topic!r} has type {schema.name!r}, which dptpu has no message type for"
    if not is_ros2_type(cls) and bytes(schema.data) != ros2_message_definition(cls).encode():
        return (f"topic {channel.topic!r} holds {schema.name} of another definition than this build's (its ros2msg "
                "schema differs from dptpu.messages.ros2_definitions')")
    return None


def _undecodable_reason(schema, channel) -> str:
    return _readable_reason(schema, channel) or f"topic {channel.topic!r} cannot be decoded"


def _converter(path: Path, schema, channel, ros2_decoders: DecoderFactory, limits: DecodeLimits
               ) -> _Converter | None:
    """How to read the records of ``channel``; None when they cannot be decoded (:func:`_readable_reason`)."""
    if _readable_reason(schema, channel) is not None:
        return None
    topic = channel.topic
    if schema.encoding == msgpack_records.ENCODING:
        try:
            cls = msgpack_records.parse_schema_data(schema.name, schema.data)
        except ValueError as error:
            raise McapReadError(f"cannot read {path}: topic {topic!r}: {error}") from None
        return lambda data: msgpack_records.unpack_message(topic, data, cls, limits=limits)
    cls = lookup(schema.name)
    if bytes(schema.data) == ros2_message_definition(cls).encode():  # our own form: the numpy decoder
        return lambda data: decode_cdr(cls, data)
    try:
        decode_ros2 = ros2_decoders.decoder_for(channel.message_encoding, schema)
    except (McapError, ValueError, NotImplementedError) as error:
        raise McapReadError(f"cannot read {path}: topic {topic!r}: its ros2msg schema {schema.name} does not "
                            f"parse ({error})") from None
    if decode_ros2 is None:  # mcap_ros2 has no decoder for this encoding (_readable_reason checked it)
        raise McapReadError(f"cannot read {path}: topic {topic!r}: no decoder for {channel.message_encoding!r}")
    return lambda data: from_ros2(cls, decode_ros2(data))
