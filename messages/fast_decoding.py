"""The decoder's fast paths: one pass over a class's plan that says yes (the message) or no (None).

They accept exactly what the general path (:mod:`.frame_reading`, :mod:`.field_decoding`) accepts; for anything
else they return None and the general path decodes the message or names the problem.
"""

from __future__ import annotations

import msgpack
import numpy as np

from .codec_plan import ARRAY_FIELD, MESSAGE_FIELD, MESSAGE_LIST_FIELD, PLANS, SCALAR_FIELD, CodecPlan, plan_for
from .decode_limits import DecodeLimits
from .field_decoding import decode_sequence
from .frame_reading import ArrayRef
from .registry import is_registered, lookup
from .wire_format import ALLOWED_DTYPES, ARRAY_INDEX, ARRAY_REF_EXT_CODE, HEADER_KEY_SET, WIRE_VERSION, DecodeError

__all__ = ["decode_well_formed", "decode_fast"]


def decode_well_formed(frames, expected, limits: DecodeLimits):
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
            view = (memoryview(frame) if kind is bytes else frame if kind is memoryview
                    else getattr(frame, "buffer", None))
            if type(view) is not memoryview or view.format != "B" or view.ndim != 1:
                return None
            total += view.nbytes
            views.append(view)
        topic_view, header_view = views[0], views[1]
        if (total > limits.max_total_bytes or not 0 < topic_view.nbytes <= limits.max_topic_bytes
                or header_view.nbytes > limits.max_header_bytes):
            return None
        header = msgpack.unpackb(header_view, raw=False, strict_map_key=True, use_list=True, ext_hook=slice)
        if type(header) is not dict or header.keys() != HEADER_KEY_SET:
            return None
        wire, type_name, version, raw, descriptors = (header["wire"], header["type"], header["version"],
                                                       header["fields"], header["arrays"])
        if type(wire) is not int or wire != WIRE_VERSION or type(type_name) is not str or not is_registered(type_name):
            return None
        cls = lookup(type_name)
        plan = PLANS.get(cls) or plan_for(cls)
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


def decode_fast(plan: CodecPlan, raw, arrays: list):
    """The message when every field is exactly as declared and every array frame is referenced exactly
    once; else None, and :func:`decode_fields` finds and names the problem. Accepts exactly what that
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


def _fast_fields(plan: CodecPlan, raw: dict, arrays: list, reference_index, used: list) -> dict | None:
    """The constructor arguments of a message of ``plan``'s class from its field map (whose keys the
    caller checked) when every field is exactly as declared, nested messages built and checked, and no
    array frame referenced twice; else None.

    ``reference_index(value)`` is the array frame an array field's header value refers to, or None when
    the value is no array reference (the two decoders unpack extension values differently); ``used[0]``
    is the bit mask of the array frames referenced so far (the caller checks that all were)."""
    fast = plan.fast
    if fast is None:  # a class nesting one without a fast plan: the general path
        return None
    values = {}
    for name, kind, python_type, low, high, dtype, ndim, extra in fast:
        value = raw[name]
        if kind == SCALAR_FIELD:
            if type(value) is not python_type or (low is not None and not low <= value <= high):
                return None
            values[name] = value
        elif kind == ARRAY_FIELD:
            index = reference_index(value)
            if index is None or index >= len(arrays) or used[0] >> index & 1:
                return None
            array = arrays[index]
            if array.ndim != ndim or (array.dtype is not dtype and array.dtype != dtype):
                return None
            used[0] |= 1 << index
            values[name] = array
        elif kind == MESSAGE_FIELD:
            nested = _fast_message(extra, value, arrays, reference_index, used)
            if nested is None:
                return None
            values[name] = nested
        elif kind == MESSAGE_LIST_FIELD:
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
                values[name] = decode_sequence(extra, value, name)
            except DecodeError:
                return None
    return values


def _fast_message(plan: CodecPlan, raw, arrays: list, reference_index, used: list):
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
            or len(value.stop) != ARRAY_INDEX.size):
        return None
    return ARRAY_INDEX.unpack(value.stop)[0]


def _array_ref_index(value) -> int | None:
    """Array frame of a header value unpacked by :func:`~.frame_reading.unpack_header`: an :class:`ArrayRef`."""
    return value.index if type(value) is ArrayRef else None
