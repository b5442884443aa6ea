"""Encoding: a message -> one ZeroMQ multipart message ``[topic, header, *arrays]`` (:mod:`.wire_format`).

:func:`encode` returns the arrays' own buffers (memoryviews, no copy): send them with
``socket.send_multipart(frames, copy=False)`` and do not modify the arrays until ZeroMQ has sent them.
A well-formed message takes a fast path over its class's plan (:mod:`.codec_plan`); anything else takes the
general path (:mod:`.field_encoding`), which checks every field and names the first one that is wrong.
"""

from __future__ import annotations

import threading

import msgpack
import numpy as np

from .codec_plan import (
    ARRAY_FIELD,
    MESSAGE_FIELD,
    MESSAGE_LIST_FIELD,
    PLANS,
    SCALAR_FIELD,
    CodecPlan,
    plan_for,
)
from .field_encoding import encode_fields, encode_sequence
from .schema import Message
from .wire_format import ARRAY_INDEX, ARRAY_REF_EXT_CODE, EncodeError, short_repr

__all__ = ["encode", "encode_checked"]

_packers = threading.local()  # one reusable msgpack.Packer per thread (a Packer is not thread-safe)


#: Header array references of the first array frames, made once (``msgpack.ExtType`` is immutable).
_ARRAY_REFS = tuple(msgpack.ExtType(ARRAY_REF_EXT_CODE, ARRAY_INDEX.pack(index)) for index in range(64))

#: The header's last key, packed: the header is ``prefix + fields + _ARRAYS_KEY + descriptors``.
_ARRAYS_KEY = msgpack.packb("arrays", use_bin_type=True)


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
    plan = PLANS.get(cls) or plan_for(cls)
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
    plan = plan_for(type(msg))
    if plan is None or not isinstance(msg, Message):
        raise EncodeError(f"msg must be a registered message (e.g. sensor_msgs Image); got {type(msg).__name__}")
    return _encode_general(topic_bytes, msg, plan)


def _encode_general(topic_bytes: bytes, msg: Message, plan: CodecPlan) -> list:
    arrays: list[np.ndarray] = []
    try:
        encoded_fields = encode_fields(msg, type(msg).__name__, arrays)
    except EncodeError as error:
        raise EncodeError(f"cannot encode {type(msg).TYPE_NAME}: {error}") from None
    descriptors = [[array.dtype.str, list(array.shape)] for array in arrays]
    return _frames(topic_bytes, plan, encoded_fields, descriptors, arrays)


def _frames(topic_bytes: bytes, plan: CodecPlan, encoded_fields: dict, descriptors: list, arrays: list) -> list:
    """``[topic, header, *array views]`` of an encoded message."""
    packer = getattr(_packers, "packer", None)
    if packer is None:
        packer = _packers.packer = msgpack.Packer(use_bin_type=True)
    header = b"".join((plan.prefix, packer.pack(encoded_fields), _ARRAYS_KEY, packer.pack(descriptors)))
    frames: list[bytes | memoryview] = [topic_bytes, header]
    for array in arrays:
        frames.append(memoryview(array.reshape(-1).view(np.uint8)))
    return frames


def _encode_fast(msg: Message, plan: CodecPlan, arrays: list, dtype_strs: list) -> dict | None:
    """The header fields of ``msg``, collecting its arrays (and their wire dtype strings) depth first in field
    order, as the general path does; None as soon as a field is not exactly of its declared kind (then the
    general path checks and raises, or converts, e.g. a numpy integer or a big-endian array)."""
    fast = plan.fast
    if fast is None:  # a class nesting one without a fast plan: the general path
        return None
    out = {}
    for name, kind, python_type, low, high, dtype, ndim, extra in fast:
        value = getattr(msg, name)
        if kind == SCALAR_FIELD:
            if type(value) is not python_type or (low is not None and not low <= value <= high):
                return None
            out[name] = value
        elif kind == ARRAY_FIELD:
            if (type(value) is not np.ndarray or value.ndim != ndim
                    or (value.dtype is not dtype and value.dtype != dtype) or len(arrays) >= len(_ARRAY_REFS)):
                return None
            if not value.flags.c_contiguous:
                value = np.ascontiguousarray(value)  # one copy into C order
            out[name] = _ARRAY_REFS[len(arrays)]
            arrays.append(value)
            dtype_strs.append(extra)
        elif kind == MESSAGE_FIELD:
            if type(value) is not extra.cls:
                return None
            nested = _encode_fast(value, extra, arrays, dtype_strs)
            if nested is None:
                return None
            out[name] = nested
        elif kind == MESSAGE_LIST_FIELD:
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
                out[name] = encode_sequence(extra, value, name)
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
        raise EncodeError(f"topic must be valid UTF-8; got {short_repr(topic)}") from None
    if not isinstance(encoded, bytes) or not encoded:
        raise EncodeError(f"topic must be a non-empty str or bytes; got {short_repr(topic)}")
    return encoded
