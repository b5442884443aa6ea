"""Wire codec: a message <-> one ZeroMQ multipart message of raw frames.

Frame layout (``docs/messages.md`` has the full specification)::

    frame 0      topic, UTF-8 bytes, e.g. b"/camera/image_raw"
    frame 1      header, one msgpack map:
                   {"wire": 1, "type": "sensor_msgs/msg/Image", "version": 1,
                    "fields": {...scalars, nested maps, inline sequences; each bulk array replaced by
                               msgpack ext type 1 holding its index, big-endian uint32...},
                    "arrays": [[dtype, [dim0, dim1, ...]], ...]}
    frame 2 + i  the raw bytes of array i, C order, little-endian

:func:`encode` returns the arrays' own buffers (memoryviews, no copy): send them with
``socket.send_multipart(frames, copy=False)`` and do not modify the arrays until ZeroMQ has sent them.
:func:`decode` returns arrays that are read-only views of the received frames (no copy). Decoding
trusts nothing: every limit of :class:`DecodeLimits`, the dtype allow-list, exact shapes and the
schema of the declared type are checked, and anything wrong raises :class:`DecodeError` (a
``ValueError``) naming the problem. The codec never uses pickle or eval.
"""

from __future__ import annotations

import struct
import threading
from dataclasses import dataclass, fields

import msgpack
import numpy as np

from .registry import is_registered, lookup
from .schema import (
    ARRAY,
    ARRAY_DTYPES,
    INTEGER_RANGES,
    MESSAGE,
    MESSAGE_LIST,
    SCALAR,
    SEQUENCE,
    FieldSpec,
    Message,
)

__all__ = ["encode", "decode", "encode_checked", "decode_checked", "DecodeError", "EncodeError", "DecodeLimits", "DEFAULT_LIMITS", "ALLOWED_DTYPES",
           "WIRE_VERSION"]

#: Version of the frame layout and header keys (not of any message type).
WIRE_VERSION = 1
#: The only msgpack extension type in a header: a reference to array frame ``2 + index``.
ARRAY_REF_EXT_CODE = 1
#: Wire dtype strings a decoder accepts (numpy ``dtype.str``), all little-endian or single-byte.
ALLOWED_DTYPES: dict[str, np.dtype] = {dtype.str: dtype for dtype in ARRAY_DTYPES.values()}

_HEADER_KEYS = ("wire", "type", "version", "fields", "arrays")
_HEADER_KEY_SET = frozenset(_HEADER_KEYS)
# primitive -> (exact Python type on the wire, inclusive integer range or None).
_SCALAR_CHECKS = {"string": (str, None, None), "float64": (float, None, None), "bool": (bool, None, None),
                  **{name: (int, low, high) for name, (low, high) in INTEGER_RANGES.items()}}
_INDEX = struct.Struct(">I")


class DecodeError(ValueError):
    """A received message is malformed, oversized, of an unexpected type or of another schema version."""


class EncodeError(ValueError):
    """A message cannot be encoded: a field has the wrong type, dtype, shape or range."""


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


class _ArrayRef:
    """A header's reference to array frame ``2 + index`` (made once per array of every decoded message)."""

    __slots__ = ("index",)

    def __init__(self, index: int):
        self.index = index

    def __repr__(self) -> str:
        return f"<array reference {self.index}>"


_packers = threading.local()  # one reusable msgpack.Packer per thread (a Packer is not thread-safe)


def _packb(value) -> bytes:
    packer = getattr(_packers, "packer", None)
    if packer is None:
        packer = _packers.packer = msgpack.Packer(use_bin_type=True)
    return packer.pack(value)


#: Header array references of the first array frames, made once (``msgpack.ExtType`` is immutable).
_ARRAY_REFS = tuple(msgpack.ExtType(ARRAY_REF_EXT_CODE, _INDEX.pack(index)) for index in range(64))
#: The header's last key, packed: the header is ``prefix + fields + _ARRAYS_KEY + descriptors``.
_ARRAYS_KEY = msgpack.packb("arrays", use_bin_type=True)


# Kinds of the fields in a plan's ``fast`` entries.
_SCALAR_FIELD, _ARRAY_FIELD, _MESSAGE_FIELD, _MESSAGE_LIST_FIELD, _SEQUENCE_FIELD = range(5)


class _Plan:
    """What the codec needs of one message class, worked out once per class (the schema is fixed).

    Attributes
    ----------
    cls : type
        The message class.
    prefix : bytes
        The packed header up to the value of ``"fields"``: a 5-entry msgpack map header, then
        ``"wire"``, ``"type"`` and ``"version"`` with their values and the key ``"fields"``. The
        header is ``prefix + packb(fields) + packb("arrays") + packb(descriptors)``, byte for byte what
        ``packb`` of the whole header map gives.
    fast : tuple or None
        One entry per field for the fast paths, ``(name, kind, python_type, low, high, dtype, ndim, extra)``:
        a scalar's exact Python type and inclusive integer range; an array's dtype, number of dimensions
        and wire dtype string (``extra``); a nested message's or a message list's element plan (``extra``);
        a sequence's FieldSpec (``extra``). None when a nested class has no fast plan (then every message
        of the class takes the general path).
    field_names : frozenset
        ``cls.FIELD_NAMES``: the keys of the class's field map.
    checks : bool
        Whether the class overrides ``Message.check_consistency`` (else calling it is skipped).
    """

    __slots__ = ("cls", "prefix", "fast", "field_names", "checks")

    def __init__(self, cls: type):
        header_start = {"wire": WIRE_VERSION, "type": cls.TYPE_NAME, "version": cls.SCHEMA_VERSION}
        packed = msgpack.packb(header_start, use_bin_type=True)
        # a 3-entry fixmap (0x83) becomes the 5-entry header (0x85); then the key "fields"
        self.prefix = b"\x85" + packed[1:] + msgpack.packb("fields", use_bin_type=True)
        self.cls = cls
        self.field_names = cls.FIELD_NAMES
        self.checks = getattr(cls, "check_consistency", None) is not Message.check_consistency
        self.fast = None

    def build_fast(self) -> None:
        """Fill :attr:`fast` (after the plan is in ``_PLANS``, so a class that nests itself finds it, still
        without a fast plan, and takes the general path)."""
        entries = []
        for spec in self.cls.FIELDS:
            kind = spec.kind
            if kind == SCALAR:
                python_type, low, high = _SCALAR_CHECKS[spec.primitive]
                entries.append((spec.name, _SCALAR_FIELD, python_type, low, high, None, 0, None))
            elif kind == ARRAY:
                entries.append((spec.name, _ARRAY_FIELD, None, None, None, spec.dtype, len(spec.axes), spec.dtype.str))
            elif kind == SEQUENCE:
                entries.append((spec.name, _SEQUENCE_FIELD, None, None, None, None, 0, spec))
            else:
                nested = _plan(spec.message_type)
                if nested is None or nested.fast is None:
                    return
                entries.append((spec.name, _MESSAGE_FIELD if kind == MESSAGE else _MESSAGE_LIST_FIELD,
                                None, None, None, None, 0, nested))
        self.fast = tuple(entries)


_PLANS: dict = {}  # message class -> _Plan (registration is permanent, so is a plan)


def _plan(cls: type) -> _Plan | None:
    """The class's plan, or None when ``cls`` is not a registered message class."""
    plan = _PLANS.get(cls)
    if plan is None:
        if not (isinstance(cls, type) and issubclass(cls, Message) and is_registered(getattr(cls, "TYPE_NAME", None))):
            return None
        plan = _PLANS[cls] = _Plan(cls)
        plan.build_fast()
    return plan


# --------------------------------------------------------------------------------------------------
# Encoding
# --------------------------------------------------------------------------------------------------

def encode(topic, msg: Message) -> list:
    """Encode ``msg`` for ``topic`` as multipart frames ``[topic, header, *arrays]``.

    Parameters
    ----------
    topic : str or bytes
        Non-empty topic name, e.g. ``"/camera/image_raw"`` (UTF-8).
    msg : Message
        A registered message (any type made with :func:`dptpu.messages.schema.message`).

    Returns
    -------
    list
        ``[topic_bytes, header_bytes, memoryview, ...]``: one memoryview per bulk array, viewing the
        array's own memory (zero-copy). An array that is not C-contiguous, or is big-endian, is made
        contiguous little-endian once (one copy) and that copy is sent.

    Raises
    ------
    EncodeError
        A field of the wrong type, dtype, number of dimensions or range, or fields that contradict
        each other (``check_consistency``); the message names the field, e.g. ``Image.height``.
    """
    topic_bytes = topic if type(topic) is bytes and topic else _topic_bytes(topic)
    cls = type(msg)
    plan = _PLANS.get(cls) or _plan(cls)
    if plan is None or not isinstance(msg, Message):
        raise EncodeError(f"msg must be a registered message (e.g. sensor_msgs Image); got {cls.__name__}")
    arrays: list[np.ndarray] = []
    dtype_strs: list[str] = []
    encoded_fields = _encode_fast(msg, plan, arrays, dtype_strs) if plan.fast is not None else None
    if encoded_fields is None:  # a field the fast path does not accept: check each one, convert or raise
        return _encode_general(topic_bytes, msg, plan)
    descriptors = [[dtype_str, list(array.shape)] for dtype_str, array in zip(dtype_strs, arrays)] if arrays else []
    return _frames(topic_bytes, plan, encoded_fields, descriptors, arrays)


def encode_checked(topic, msg: Message) -> list:
    """:func:`encode` by the general path only: every field checked and converted one by one.

    The same frames as :func:`encode` (which takes a precomputed fast path for well-formed messages and
    falls back to this one); here for tests and ``dptpu bench codec``, which compare the two.
    """
    topic_bytes = topic if type(topic) is bytes and topic else _topic_bytes(topic)
    plan = _plan(type(msg))
    if plan is None or not isinstance(msg, Message):
        raise EncodeError(f"msg must be a registered message (e.g. sensor_msgs Image); got {type(msg).__name__}")
    return _encode_general(topic_bytes, msg, plan)


def _encode_general(topic_bytes: bytes, msg: Message, plan: _Plan) -> list:
    arrays: list[np.ndarray] = []
    try:
        encoded_fields = _encode_fields(msg, type(msg).__name__, arrays)
    except EncodeError as error:
        raise EncodeError(f"cannot encode {type(msg).TYPE_NAME}: {error}") from None
    descriptors = [[array.dtype.str, list(array.shape)] for array in arrays]
    return _frames(topic_bytes, plan, encoded_fields, descriptors, arrays)


def _frames(topic_bytes: bytes, plan: _Plan, encoded_fields: dict, descriptors: list, arrays: list) -> list:
    """``[topic, header, *array views]`` of an encoded message."""
    packer = getattr(_packers, "packer", None)
    if packer is None:
        packer = _packers.packer = msgpack.Packer(use_bin_type=True)
    frames = [topic_bytes, b"".join((plan.prefix, packer.pack(encoded_fields), _ARRAYS_KEY, packer.pack(descriptors)))]
    for array in arrays:
        frames.append(memoryview(array.reshape(-1).view(np.uint8)))
    return frames


def _encode_fast(msg: Message, plan: _Plan, arrays: list, dtype_strs: list) -> dict | None:
    """The header fields of ``msg``, collecting its arrays (and their wire dtype strings) depth first in field
    order, as the general path does; None as soon as a field is not exactly of its declared kind (then the
    general path checks and raises, or converts, e.g. a numpy integer or a big-endian array)."""
    out = {}
    for name, kind, python_type, low, high, dtype, ndim, extra in plan.fast:
        value = getattr(msg, name)
        if kind == _SCALAR_FIELD:
            if type(value) is not python_type or (low is not None and not low <= value <= high):
                return None
            out[name] = value
        elif kind == _ARRAY_FIELD:
            if (type(value) is not np.ndarray or value.ndim != ndim or (value.dtype is not dtype and value.dtype != dtype)
                    or len(arrays) >= len(_ARRAY_REFS)):
                return None
            if not value.flags.c_contiguous:
                value = np.ascontiguousarray(value)  # one copy into C order
            out[name] = _ARRAY_REFS[len(arrays)]
            arrays.append(value)
            dtype_strs.append(extra)
        elif kind == _MESSAGE_FIELD:
            if type(value) is not extra.cls:
                return None
            nested = _encode_fast(value, extra, arrays, dtype_strs)
            if nested is None:
                return None
            out[name] = nested
        elif kind == _MESSAGE_LIST_FIELD:
            if type(value) is not list and type(value) is not tuple:
                return None
            items = []
            for item in value:
                nested = _encode_fast(item, extra, arrays, dtype_strs) if type(item) is extra.cls else None
                if nested is None:
                    return None
                items.append(nested)
            out[name] = items
        else:  # a sequence: the general path's conversion; an EncodeError sends the message there
            try:
                out[name] = _encode_sequence(extra, value, name)
            except EncodeError:
                return None
    if plan.checks:
        try:
            msg.check_consistency()
        except ValueError:
            return None  # the general path raises it with the field's place
    return out


def _topic_bytes(topic) -> bytes:
    try:
        encoded = topic.encode("utf-8") if isinstance(topic, str) else topic
    except UnicodeEncodeError:
        raise EncodeError(f"topic must be valid UTF-8; got {_short_repr(topic)}") from None
    if not isinstance(encoded, bytes) or not encoded:
        raise EncodeError(f"topic must be a non-empty str or bytes; got {_short_repr(topic)}")
    return encoded


def _encode_fields(msg: Message, path: str, arrays: list) -> dict:
    out = {}
    for spec in type(msg).FIELDS:
        value = getattr(msg, spec.name)
        kind = spec.kind
        if kind == SCALAR:
            python_type, low, high = _SCALAR_CHECKS[spec.primitive]
            if type(value) is python_type and (low is None or low <= value <= high):
                out[spec.name] = value  # fast path: a builtin of the right type and range
            else:
                out[spec.name] = _encode_scalar(spec.primitive, value, f"{path}.{spec.name}")
            continue
        if kind == ARRAY:
            out[spec.name] = msgpack.ExtType(ARRAY_REF_EXT_CODE, _INDEX.pack(len(arrays)))
            arrays.append(_encode_array(spec, value, path))
            continue
        where = f"{path}.{spec.name}"
        if kind == MESSAGE:
            _check_nested_type(spec, value, where)
            out[spec.name] = _encode_fields(value, where, arrays)
        elif kind == MESSAGE_LIST:
            if not isinstance(value, (list, tuple)):
                raise EncodeError(f"{where} must be a list of {spec.message_type.__name__}; got {type(value).__name__}")
            items = []
            for index, item in enumerate(value):
                _check_nested_type(spec, item, f"{where}[{index}]")
                items.append(_encode_fields(item, f"{where}[{index}]", arrays))
            out[spec.name] = items
        else:  # SEQUENCE
            out[spec.name] = _encode_sequence(spec, value, where)
    try:
        msg.check_consistency()
    except ValueError as error:  # the error names the class; add where it sits when nested
        raise EncodeError(str(error) if path == type(msg).__name__ else f"{path}: {error}") from None
    return out


def _check_nested_type(spec: FieldSpec, value, where: str) -> None:
    if type(value) is not spec.message_type:
        raise EncodeError(f"{where} must be a {spec.message_type.__name__}; got {type(value).__name__}")


def _encode_scalar(primitive: str, value, where: str):
    if primitive == "string":
        if isinstance(value, str):
            return str(value)
    elif primitive == "bool":
        if isinstance(value, (bool, np.bool_)):
            return bool(value)
    elif isinstance(value, (bool, np.bool_)):
        pass  # a bool is not a number here
    elif primitive == "float64":
        if isinstance(value, (float, int, np.floating, np.integer)):
            try:
                return float(value)
            except OverflowError:
                raise EncodeError(f"{where} is too large for float64; got {_short_repr(value)}") from None
    elif isinstance(value, (int, np.integer)):
        number = int(value)
        low, high = INTEGER_RANGES[primitive]
        if low <= number <= high:
            return number
        raise EncodeError(f"{where} must be {primitive} in [{low}, {high}]; got {number}")
    raise EncodeError(f"{where} must be {primitive}; got {type(value).__name__} {_short_repr(value)}")


def _encode_sequence(spec: FieldSpec, value, where: str) -> list:
    try:
        values = np.asarray(value)
    except (ValueError, TypeError) as error:
        raise EncodeError(f"{where} must be a 1-D sequence of {spec.primitive}; got {_short_repr(value)} "
                          f"({error})") from None
    expected = f"{spec.length}" if spec.length is not None else "n"
    if values.ndim != 1 or (spec.length is not None and values.shape[0] != spec.length):
        raise EncodeError(f"{where} must have shape ({expected},); got {values.shape}")
    kind = values.dtype.kind
    target = spec.dtype
    if target.kind == "f":
        ok = kind in "fiu"
    elif target.kind == "b":
        ok = kind == "b"
    else:
        ok = kind in "iu"
        if ok and values.size:
            low, high = INTEGER_RANGES[spec.primitive]
            ok = low <= int(values.min()) and int(values.max()) <= high
    if not ok:
        raise EncodeError(f"{where} must hold {spec.primitive} values; got dtype {values.dtype} {_short_repr(value)}")
    return values.astype(target, copy=False).tolist()


def _encode_array(spec: FieldSpec, value, path: str) -> np.ndarray:
    target = spec.dtype
    if type(value) is np.ndarray and value.dtype == target and value.ndim == len(spec.axes):
        # fast path: the right dtype (hence little-endian or single-byte) and number of dimensions
        return value if value.flags.c_contiguous else np.ascontiguousarray(value)  # one copy into C order
    where = f"{path}.{spec.name}"
    axes = f"({', '.join(spec.axes)})"
    if not isinstance(value, np.ndarray):
        raise EncodeError(f"{where} must be a numpy ndarray {axes} of {spec.primitive}; got {type(value).__name__}")
    if value.ndim != len(spec.axes):
        raise EncodeError(f"{where} must have {len(spec.axes)} dimension(s) {axes}; got shape {value.shape}")
    if value.dtype.newbyteorder("<") != target:
        raise EncodeError(f"{where} must have dtype {spec.primitive} ({target.str}); got {value.dtype} "
                          f"(convert with .astype(np.{target.name}))")
    if value.dtype != target:  # big-endian: one copy into little-endian
        return value.astype(target, order="C")
    if not value.flags.c_contiguous:  # one copy into C order
        return np.ascontiguousarray(value)
    return value


def _short_repr(value) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


# --------------------------------------------------------------------------------------------------
# Decoding
# --------------------------------------------------------------------------------------------------

def decode(frames, *, expected_type=None, limits: DecodeLimits = DEFAULT_LIMITS):
    """Decode multipart frames ``[topic, header, *arrays]`` into ``(topic, message)``.

    Parameters
    ----------
    frames : list or tuple
        The received frames: ``bytes``, ``bytearray``, ``memoryview`` or ``zmq.Frame``-like objects with
        a ``.buffer``. Array frames are viewed, not copied: the returned arrays keep them alive.
    expected_type : type or str, optional
        A message class or type name (``"sensor_msgs/msg/Image"``); another type raises DecodeError.
    limits : DecodeLimits
        Upper bounds on frames, bytes, dimensions and elements.

    Returns
    -------
    topic : str
    msg : Message
        Bulk arrays are read-only numpy views of the array frames; inline sequences (e.g.
        ``CameraInfo.k``) are new writable arrays.

    Raises
    ------
    DecodeError
        Too many frames or bytes, a malformed topic or header, an unknown type, a schema version
        mismatch, a dtype outside :data:`ALLOWED_DTYPES`, a shape that does not match its frame's
        length exactly, missing, unknown or mistyped fields, or inconsistent fields. The message
        starts with the topic and type when they are known.
    ValueError
        ``expected_type`` or ``limits`` is not valid (a caller error, not a bad message).
    """
    if not isinstance(limits, DecodeLimits):
        raise ValueError(f"limits must be a DecodeLimits; got {type(limits).__name__}")
    expected = expected_type if expected_type in _EXPECTED_CLASSES else _expected_class(expected_type)
    decoded = _decode_well_formed(frames, expected, limits)
    if decoded is not None:
        return decoded
    return _decode_general(frames, expected, limits)


def decode_checked(frames, *, expected_type=None, limits: DecodeLimits = DEFAULT_LIMITS):
    """:func:`decode` by the general path only: every limit and field checked one by one.

    The same result or the same :class:`DecodeError` as :func:`decode` (which first tries a one-pass fast
    path for well-formed messages); here for tests and ``dptpu bench codec``, which compare the two.
    """
    if not isinstance(limits, DecodeLimits):
        raise ValueError(f"limits must be a DecodeLimits; got {type(limits).__name__}")
    return _decode_general(frames, _expected_class(expected_type), limits)


def _decode_general(frames, expected, limits: DecodeLimits):
    """The general path: checks everything one by one and names the first problem."""
    topic = cls = None
    try:
        views = _frame_views(frames, limits)
        topic = _decode_topic(views[0], limits)
        header = _unpack_header(views[1], limits)
        cls = _header_class(header, expected, len(views) - 2)
        arrays = [_array_view(index, descriptor, view, limits)
                  for index, (descriptor, view) in enumerate(zip(header["arrays"], views[2:]))]
        plan = _PLANS.get(cls) or _plan(cls)
        msg = _decode_fast(plan, header["fields"], arrays) if plan.fast is not None else None
        if msg is None:  # nested fields, or anything the fast path does not accept: check each one
            used = [False] * len(arrays)
            msg = _decode_fields(cls, header["fields"], arrays, used, cls.__name__)
            if not all(used):
                raise DecodeError(f"array frame(s) {[i for i, u in enumerate(used) if not u]} are not referenced "
                                  "by any field")
    except DecodeError as error:
        context = "cannot decode message"
        if topic is not None:
            context += f" on topic {topic!r}"
        if cls is not None:
            context += f" of type {cls.TYPE_NAME}"
        raise DecodeError(f"{context}: {error}") from None
    return topic, msg


def _decode_well_formed(frames, expected, limits: DecodeLimits):
    """``(topic, msg)`` of a well-formed message, or None.

    The fast path for the common case: the same checks as the general path, in one pass over the class's
    plan, but it only says yes or no; for anything else (a malformed or oversized message, an unexpected
    type, a class without a fast plan) it returns None and the general path decodes the message or raises the
    DecodeError that names the problem. It must never accept what the general path rejects.

    The header is unpacked with ``ext_hook=slice``, a C constructor, instead of the checking hook:
    an extension value becomes ``slice(code, data)``, which only an array field accepts, and only as
    a 4-byte reference of code ``ARRAY_REF_EXT_CODE``; anywhere else it fails a type check.
    """
    try:
        count = len(frames)
        if type(frames) not in (list, tuple) or not 2 <= count <= limits.max_frames:
            return None
        views = []
        total = 0
        for frame in frames:
            kind = type(frame)
            view = memoryview(frame) if kind is bytes else frame if kind is memoryview else getattr(frame, "buffer", None)
            if type(view) is not memoryview or view.format != "B" or view.ndim != 1:
                return None
            total += view.nbytes
            views.append(view)
        topic_view, header_view = views[0], views[1]
        if (total > limits.max_total_bytes or not 0 < topic_view.nbytes <= limits.max_topic_bytes
                or header_view.nbytes > limits.max_header_bytes):
            return None
        header = msgpack.unpackb(header_view, raw=False, strict_map_key=True, use_list=True, ext_hook=slice)
        if type(header) is not dict or header.keys() != _HEADER_KEY_SET:
            return None
        wire, type_name, version, raw, descriptors = (header["wire"], header["type"], header["version"],
                                                       header["fields"], header["arrays"])
        if type(wire) is not int or wire != WIRE_VERSION or type(type_name) is not str or not is_registered(type_name):
            return None
        cls = lookup(type_name)
        plan = _PLANS.get(cls) or _plan(cls)
        if (plan is None or plan.fast is None or (expected is not None and cls is not expected)
                or type(version) is not int or version != cls.SCHEMA_VERSION or type(descriptors) is not list
                or len(descriptors) != count - 2 or type(raw) is not dict or raw.keys() != plan.field_names):
            return None
        arrays = []
        max_ndim, max_elements, max_bytes = limits.max_ndim, limits.max_dims_product, limits.max_array_bytes
        for descriptor, view in zip(descriptors, views[2:]):
            if type(descriptor) is not list or len(descriptor) != 2:
                return None
            dtype_name, shape = descriptor
            dtype = ALLOWED_DTYPES.get(dtype_name) if type(dtype_name) is str else None
            if dtype is None or type(shape) is not list or len(shape) > max_ndim:
                return None
            elements = 1
            for size in shape:
                if type(size) is not int or not 0 <= size <= max_elements:
                    return None
                elements *= size
                if elements > max_elements:
                    return None
            nbytes = elements * dtype.itemsize
            if nbytes != view.nbytes or nbytes > max_bytes:
                return None
            values = np.frombuffer(view, dtype=dtype)  # read-only when the buffer is (a received frame)
            if len(shape) != 1:
                values = values.reshape(shape)
            if not view.readonly:
                values.flags.writeable = False
            arrays.append(values)
        used = [0]
        fields = _fast_fields(plan, raw, arrays, _slice_reference_index, used)
        if fields is None or used[0] != (1 << len(arrays)) - 1:  # every array frame referenced exactly once
            return None
        msg = cls(**fields)
        if plan.checks:
            msg.check_consistency()
        return str(topic_view, "utf-8"), msg
    except Exception:  # noqa: BLE001 -- anything unexpected: the general path decides and names it
        return None


def _decode_fast(plan: _Plan, raw, arrays: list):
    """The message when every field is exactly as declared and every array frame is referenced exactly
    once; else None, and :func:`_decode_fields` finds and names the problem. Accepts exactly what that
    general path accepts."""
    if type(raw) is not dict or raw.keys() != plan.field_names:
        return None
    used = [0]
    values = _fast_fields(plan, raw, arrays, _array_ref_index, used)
    if values is None or used[0] != (1 << len(arrays)) - 1:
        return None
    msg = plan.cls(**values)
    if plan.checks:
        try:
            msg.check_consistency()
        except ValueError:
            return None
    return msg


def _fast_fields(plan: _Plan, raw: dict, arrays: list, reference_index, used: list) -> dict | None:
    """The constructor arguments of a message of ``plan``'s class from its field map (whose keys the
    caller checked) when every field is exactly as declared, nested messages built and checked, and no
    array frame referenced twice; else None.

    ``reference_index(value)`` is the array frame an array field's header value refers to, or None when
    the value is no array reference (the two decoders unpack extension values differently); ``used[0]``
    is the bit mask of the array frames referenced so far (the caller checks that all were)."""
    values = {}
    for name, kind, python_type, low, high, dtype, ndim, extra in plan.fast:
        value = raw[name]
        if kind == _SCALAR_FIELD:
            if type(value) is not python_type or (low is not None and not low <= value <= high):
                return None
            values[name] = value
        elif kind == _ARRAY_FIELD:
            index = reference_index(value)
            if index is None or index >= len(arrays) or used[0] >> index & 1:
                return None
            array = arrays[index]
            if array.ndim != ndim or (array.dtype is not dtype and array.dtype != dtype):
                return None
            used[0] |= 1 << index
            values[name] = array
        elif kind == _MESSAGE_FIELD:
            nested = _fast_message(extra, value, arrays, reference_index, used)
            if nested is None:
                return None
            values[name] = nested
        elif kind == _MESSAGE_LIST_FIELD:
            if type(value) is not list:
                return None
            items = []
            for item in value:
                nested = _fast_message(extra, item, arrays, reference_index, used)
                if nested is None:
                    return None
                items.append(nested)
            values[name] = items
        else:  # a sequence: the general path's check; a DecodeError sends the message there
            try:
                values[name] = _decode_sequence(extra, value, name)
            except DecodeError:
                return None
    return values


def _fast_message(plan: _Plan, raw, arrays: list, reference_index, used: list):
    """A nested message of ``plan``'s class from its field map, built and checked; else None."""
    if type(raw) is not dict or raw.keys() != plan.field_names:
        return None
    values = _fast_fields(plan, raw, arrays, reference_index, used)
    if values is None:
        return None
    msg = plan.cls(**values)
    if plan.checks:
        try:
            msg.check_consistency()
        except ValueError:
            return None
    return msg


def _slice_reference_index(value) -> int | None:
    """Array frame of a header value unpacked with ``ext_hook=slice``: ``slice(code, 4-byte index)``."""
    if (type(value) is not slice or value.start != ARRAY_REF_EXT_CODE or type(value.stop) is not bytes
            or len(value.stop) != _INDEX.size):
        return None
    return _INDEX.unpack(value.stop)[0]


def _array_ref_index(value) -> int | None:
    """Array frame of a header value unpacked by :func:`_ext_hook`: an :class:`_ArrayRef`."""
    return value.index if type(value) is _ArrayRef else None


_EXPECTED_CLASSES: set = set()  # message classes already accepted as expected_type (registration is permanent)


def _expected_class(expected_type):
    if expected_type is None:
        return None
    if expected_type in _EXPECTED_CLASSES:
        return expected_type
    if isinstance(expected_type, str):
        try:
            return lookup(expected_type)
        except KeyError as error:
            raise ValueError(f"expected_type: {error.args[0]}") from None
    if isinstance(expected_type, type) and issubclass(expected_type, Message) \
            and is_registered(getattr(expected_type, "TYPE_NAME", None)):
        _EXPECTED_CLASSES.add(expected_type)
        return expected_type
    raise ValueError(f"expected_type must be a message class or type name; got {expected_type!r}")


def _frame_views(frames, limits: DecodeLimits) -> list[memoryview]:
    if not isinstance(frames, (list, tuple)):
        raise DecodeError(f"frames must be a list of frames; got {type(frames).__name__}")
    if len(frames) < 2:
        raise DecodeError(f"a message needs at least 2 frames (topic, header); got {len(frames)}")
    if len(frames) > limits.max_frames:
        raise DecodeError(f"too many frames: {len(frames)} > max_frames {limits.max_frames}")
    views, total = [], 0
    for index, frame in enumerate(frames):
        if type(frame) is bytes:
            view = memoryview(frame)
        else:
            view = getattr(frame, "buffer", None)  # a zmq.Frame: its memoryview, format "B"
            if type(view) is not memoryview or view.format != "B" or view.ndim != 1:
                view = _byte_view(frame, index)
        total += view.nbytes
        if total > limits.max_total_bytes:
            raise DecodeError(f"frames hold more than max_total_bytes {limits.max_total_bytes} bytes")
        views.append(view)
    return views


def _byte_view(frame, index: int) -> memoryview:
    source = frame if isinstance(frame, (bytes, bytearray, memoryview)) else getattr(frame, "buffer", frame)
    try:
        view = memoryview(source)
    except TypeError:
        raise DecodeError(f"frame {index} is a {type(frame).__name__}; expected bytes, memoryview or a "
                          "zmq.Frame") from None
    if view.format in ("B", "b", "c") and view.ndim == 1:
        return view if view.format == "B" else view.cast("B")
    if not view.c_contiguous:
        raise DecodeError(f"frame {index} is not a contiguous buffer")
    try:
        return view.cast("B")
    except (TypeError, ValueError):
        raise DecodeError(f"frame {index} cannot be read as bytes (buffer format {view.format!r})") from None


def _decode_topic(view: memoryview, limits: DecodeLimits) -> str:
    if view.nbytes > limits.max_topic_bytes:
        raise DecodeError(f"topic frame has {view.nbytes} bytes > max_topic_bytes {limits.max_topic_bytes}")
    if view.nbytes == 0:
        raise DecodeError("topic frame is empty")
    try:
        return str(view, "utf-8")
    except UnicodeDecodeError:
        raise DecodeError("topic frame is not valid UTF-8") from None


def _ext_hook(code: int, data: bytes):
    if code != ARRAY_REF_EXT_CODE:
        raise DecodeError(f"header holds msgpack extension type {code}; only {ARRAY_REF_EXT_CODE} (array "
                          "reference) is allowed")
    if len(data) != _INDEX.size:
        raise DecodeError(f"array reference must hold a 4-byte index; got {len(data)} bytes")
    return _ArrayRef(_INDEX.unpack(data)[0])


def _unpack_header(view: memoryview, limits: DecodeLimits) -> dict:
    if view.nbytes > limits.max_header_bytes:
        raise DecodeError(f"header frame has {view.nbytes} bytes > max_header_bytes {limits.max_header_bytes}")
    try:
        header = msgpack.unpackb(view, raw=False, strict_map_key=True, use_list=True, ext_hook=_ext_hook)
    except DecodeError:
        raise
    except (ValueError, TypeError, OverflowError, RecursionError, msgpack.UnpackException) as error:
        detail = str(error) or "nested too deeply"
        raise DecodeError(f"header is not valid msgpack ({type(error).__name__}: {detail})") from None
    if type(header) is not dict:
        raise DecodeError(f"header must be a msgpack map; got {type(header).__name__}")
    if header.keys() != _HEADER_KEY_SET:
        missing = [key for key in _HEADER_KEYS if key not in header]
        unknown = [key for key in header if key not in _HEADER_KEYS]
        raise DecodeError(f"header must have exactly the keys {', '.join(_HEADER_KEYS)}; "
                          f"missing {missing}, unknown {[_short_repr(k) for k in unknown]}")
    wire = header["wire"]
    if type(wire) is not int or wire != WIRE_VERSION:
        raise DecodeError(f"wire format version {_short_repr(wire)} is not supported; expected {WIRE_VERSION}")
    return header


def _header_class(header: dict, expected, array_frames: int) -> type:
    type_name = header["type"]
    if not is_registered(type_name):
        raise DecodeError(f"unknown message type {_short_repr(type_name)}")
    cls = lookup(type_name)
    if expected is not None and cls is not expected:
        raise DecodeError(f"expected a {expected.TYPE_NAME}; got a {type_name}")
    version = header["version"]
    if type(version) is not int or version != cls.SCHEMA_VERSION:
        raise DecodeError(f"schema version mismatch for {type_name}: the message has version "
                          f"{_short_repr(version)}, this build has {cls.SCHEMA_VERSION}")
    descriptors = header["arrays"]
    if type(descriptors) is not list:
        raise DecodeError(f"header 'arrays' must be a list of [dtype, shape]; got {type(descriptors).__name__}")
    if len(descriptors) != array_frames:
        raise DecodeError(f"header declares {len(descriptors)} array(s) but {array_frames} array frame(s) came")
    return cls


def _array_view(index: int, descriptor, view: memoryview, limits: DecodeLimits) -> np.ndarray:
    if type(descriptor) is list and len(descriptor) == 2:  # fast path: a well-formed descriptor within limits
        dtype_name, shape = descriptor
        dtype = ALLOWED_DTYPES.get(dtype_name) if type(dtype_name) is str else None
        if dtype is not None and type(shape) is list and len(shape) <= limits.max_ndim:
            bound = limits.max_dims_product
            elements = 1
            for size in shape:
                if type(size) is not int or not 0 <= size <= bound:
                    break
                elements *= size
                if elements > bound:
                    break
            else:
                nbytes = elements * dtype.itemsize
                if nbytes == view.nbytes and nbytes <= limits.max_array_bytes:
                    values = np.frombuffer(view, dtype=dtype).reshape(shape)
                    values.flags.writeable = False
                    return values
    # the same checks one by one, raising the first that fails
    if type(descriptor) is not list or len(descriptor) != 2:
        raise DecodeError(f"array {index}: descriptor must be [dtype, shape]; got {_short_repr(descriptor)}")
    dtype_name, shape = descriptor
    dtype = ALLOWED_DTYPES.get(dtype_name) if type(dtype_name) is str else None
    if dtype is None:
        raise DecodeError(f"array {index}: dtype {_short_repr(dtype_name)} is not allowed; allowed dtypes: "
                          f"{', '.join(ALLOWED_DTYPES)}")
    if type(shape) is not list or not all(type(size) is int and size >= 0 for size in shape):
        raise DecodeError(f"array {index}: shape must be a list of non-negative ints; got {_short_repr(shape)}")
    if len(shape) > limits.max_ndim:
        raise DecodeError(f"array {index}: {len(shape)} dimensions > max_ndim {limits.max_ndim}")
    elements = 1
    for size in shape:  # every dimension is bounded, even when another one is 0
        elements *= size
        if size > limits.max_dims_product or elements > limits.max_dims_product:
            raise DecodeError(f"array {index}: shape {_short_repr(shape)} has more than max_dims_product "
                              f"{limits.max_dims_product} elements")
    nbytes = elements * dtype.itemsize
    if nbytes > limits.max_array_bytes:
        raise DecodeError(f"array {index}: {nbytes} bytes > max_array_bytes {limits.max_array_bytes}")
    if nbytes != view.nbytes:
        raise DecodeError(f"array {index}: shape {shape} of {dtype_name} needs {nbytes} bytes; its frame has "
                          f"{view.nbytes}")
    values = np.frombuffer(view, dtype=dtype).reshape(shape)
    values.flags.writeable = False
    return values


def _decode_fields(cls: type, raw, arrays: list, used: list, path: str) -> Message:
    if type(raw) is not dict:
        raise DecodeError(f"{path} must be a map of fields; got {type(raw).__name__}")
    specs = cls.FIELDS
    if raw.keys() != cls.FIELD_NAMES:
        missing = [spec.name for spec in specs if spec.name not in raw]
        unknown = [_short_repr(key) for key in raw if key not in cls.FIELD_NAMES]
        raise DecodeError(f"{path}: fields do not match {cls.TYPE_NAME} version {cls.SCHEMA_VERSION}: "
                          f"missing {missing}, unknown {unknown}")
    values = {}
    for spec in specs:
        value = raw[spec.name]
        kind = spec.kind
        if kind == SCALAR:
            values[spec.name] = _decode_scalar(spec.primitive, value, path, spec.name)
            continue
        if kind == ARRAY:
            values[spec.name] = _decode_array_ref(spec, value, arrays, used, path)
            continue
        where = f"{path}.{spec.name}"
        if kind == MESSAGE:
            values[spec.name] = _decode_fields(spec.message_type, value, arrays, used, where)
        elif kind == MESSAGE_LIST:
            if type(value) is not list:
                raise DecodeError(f"{where} must be a list; got {type(value).__name__}")
            values[spec.name] = [_decode_fields(spec.message_type, item, arrays, used, f"{where}[{index}]")
                                 for index, item in enumerate(value)]
        else:  # SEQUENCE
            values[spec.name] = _decode_sequence(spec, value, where)
    msg = cls(**values)
    try:
        msg.check_consistency()
    except ValueError as error:  # the error names the class; add where it sits when nested
        raise DecodeError(str(error) if path == type(msg).__name__ else f"{path}: {error}") from None
    return msg


def _decode_scalar(primitive: str, value, path: str, name: str):
    python_type, low, high = _SCALAR_CHECKS[primitive]
    if type(value) is not python_type or (low is not None and not low <= value <= high):
        raise DecodeError(f"{path}.{name} must be {primitive}; got {type(value).__name__} {_short_repr(value)}")
    return value


def _decode_sequence(spec: FieldSpec, value, where: str) -> np.ndarray:
    if type(value) is not list or (spec.length is not None and len(value) != spec.length):
        length = spec.length if spec.length is not None else "any number of"
        raise DecodeError(f"{where} must be a list of {length} {spec.primitive}; got {_short_repr(value)}")
    python_type, low, high = _SCALAR_CHECKS[spec.primitive]
    for index, item in enumerate(value):
        if type(item) is not python_type or (low is not None and not low <= item <= high):
            raise DecodeError(f"{where}[{index}] must be {spec.primitive}; got {type(item).__name__} "
                              f"{_short_repr(item)}")
    return np.array(value, dtype=spec.dtype)


def _decode_array_ref(spec: FieldSpec, value, arrays: list, used: list, path: str) -> np.ndarray:
    if type(value) is _ArrayRef:  # fast path: a valid, unused reference to an array of the right dtype and rank
        index = value.index
        if index < len(arrays) and not used[index]:
            values = arrays[index]
            if values.dtype == spec.dtype and values.ndim == len(spec.axes):
                used[index] = True
                return values
    where = f"{path}.{spec.name}"
    if type(value) is not _ArrayRef:
        raise DecodeError(f"{where} must be an array reference; got {type(value).__name__} {_short_repr(value)}")
    index = value.index
    if index >= len(arrays):
        raise DecodeError(f"{where} refers to array {index}; the message has {len(arrays)} array(s)")
    if used[index]:
        raise DecodeError(f"{where} refers to array {index}, which another field already uses")
    values = arrays[index]
    if values.dtype != spec.dtype:
        raise DecodeError(f"{where} must have dtype {spec.primitive} ({spec.dtype.str}); got {values.dtype.str}")
    raise DecodeError(f"{where} must have {len(spec.axes)} dimension(s) ({', '.join(spec.axes)}); "
                      f"got shape {values.shape}")
    if values.dtype != spec.dtype:
        raise DecodeError(f"{where} must have dtype {spec.primitive} ({spec.dtype.str}); got {values.dtype.str}")
    if values.ndim != len(spec.axes):
        raise DecodeError(f"{where} must have {len(spec.axes)} dimension(s) ({', '.join(spec.axes)}); "
                          f"got shape {values.shape}")
    return values
