"""The decoder's reading of frames: byte views within the limits, the topic, the header, the array views.

Each function checks one part of a received message and raises :class:`DecodeError` naming what is wrong.
"""

from __future__ import annotations

import msgpack
import numpy as np

from .decode_limits import DecodeLimits
from .registry import is_registered, lookup
from .wire_format import (
    ALLOWED_DTYPES,
    ARRAY_INDEX,
    ARRAY_REF_EXT_CODE,
    HEADER_KEY_SET,
    HEADER_KEYS,
    WIRE_VERSION,
    DecodeError,
    short_repr,
)

__all__ = ["ArrayRef", "frame_views", "decode_topic", "unpack_header", "header_class", "array_view"]


class ArrayRef:
    """A header's reference to array frame ``2 + index`` (made once per array of every decoded message)."""

    __slots__ = ("index",)

    def __init__(self, index: int):
        self.index = index

    def __repr__(self) -> str:
        return f"<array reference {self.index}>"


def frame_views(frames, limits: DecodeLimits) -> list[memoryview]:
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
            buffer = getattr(frame, "buffer", None)  # a zmq.Frame: its memoryview, format "B"
            if type(buffer) is memoryview and buffer.format == "B" and buffer.ndim == 1:
                view = buffer
            else:
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


def decode_topic(view: memoryview, limits: DecodeLimits) -> str:
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
    if len(data) != ARRAY_INDEX.size:
        raise DecodeError(f"array reference must hold a 4-byte index; got {len(data)} bytes")
    return ArrayRef(ARRAY_INDEX.unpack(data)[0])


def unpack_header(view: memoryview, limits: DecodeLimits) -> dict:
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
    if header.keys() != HEADER_KEY_SET:
        missing = [key for key in HEADER_KEYS if key not in header]
        unknown = [key for key in header if key not in HEADER_KEYS]
        raise DecodeError(f"header must have exactly the keys {', '.join(HEADER_KEYS)}; "
                          f"missing {missing}, unknown {[short_repr(k) for k in unknown]}")
    wire = header["wire"]
    if type(wire) is not int or wire != WIRE_VERSION:
        raise DecodeError(f"wire format version {short_repr(wire)} is not supported; expected {WIRE_VERSION}")
    return header


def header_class(header: dict, expected, array_frames: int) -> type:
    type_name = header["type"]
    if not is_registered(type_name):
        raise DecodeError(f"unknown message type {short_repr(type_name)}")
    cls = lookup(type_name)
    if expected is not None and cls is not expected:
        raise DecodeError(f"expected a {expected.TYPE_NAME}; got a {type_name}")
    version = header["version"]
    if type(version) is not int or version != cls.SCHEMA_VERSION:
        raise DecodeError(f"schema version mismatch for {type_name}: the message has version "
                          f"{short_repr(version)}, this build has {cls.SCHEMA_VERSION}")
    descriptors = header["arrays"]
    if type(descriptors) is not list:
        raise DecodeError(f"header 'arrays' must be a list of [dtype, shape]; got {type(descriptors).__name__}")
    if len(descriptors) != array_frames:
        raise DecodeError(f"header declares {len(descriptors)} array(s) but {array_frames} array frame(s) came")
    return cls


def array_view(index: int, descriptor, view: memoryview, limits: DecodeLimits) -> np.ndarray:
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
        raise DecodeError(f"array {index}: descriptor must be [dtype, shape]; got {short_repr(descriptor)}")
    dtype_name, shape = descriptor
    dtype = ALLOWED_DTYPES.get(dtype_name) if type(dtype_name) is str else None
    if dtype is None:
        raise DecodeError(f"array {index}: dtype {short_repr(dtype_name)} is not allowed; allowed dtypes: "
                          f"{', '.join(ALLOWED_DTYPES)}")
    if type(shape) is not list or not all(type(size) is int and size >= 0 for size in shape):
        raise DecodeError(f"array {index}: shape must be a list of non-negative ints; got {short_repr(shape)}")
    if len(shape) > limits.max_ndim:
        raise DecodeError(f"array {index}: {len(shape)} dimensions > max_ndim {limits.max_ndim}")
    elements = 1
    for size in shape:  # every dimension is bounded, even when another one is 0
        elements *= size
        if size > limits.max_dims_product or elements > limits.max_dims_product:
            raise DecodeError(f"array {index}: shape {short_repr(shape)} has more than max_dims_product "
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
