"""The decoder's general path over a header's fields: each one checked against the schema, the first problem named."""

from __future__ import annotations

from typing import Any

import numpy as np

from .field_spec import ARRAY, MESSAGE, MESSAGE_LIST, SCALAR, FieldSpec
from .frame_reading import ArrayRef
from .schema import Message
from .wire_format import SCALAR_CHECKS, DecodeError, short_repr

__all__ = ["decode_fields", "decode_sequence"]


def decode_fields(cls: type[Message], raw: object, arrays: list[np.ndarray], used: list[bool], path: str) -> Message:
    if type(raw) is not dict:
        raise DecodeError(f"{path} must be a map of fields; got {type(raw).__name__}")
    specs = cls.FIELDS
    if raw.keys() != cls.FIELD_NAMES:
        missing = [spec.name for spec in specs if spec.name not in raw]
        unknown = [short_repr(key) for key in raw if key not in cls.FIELD_NAMES]
        raise DecodeError(f"{path}: fields do not match {cls.TYPE_NAME} version {cls.SCHEMA_VERSION}: "
                          f"missing {missing}, unknown {unknown}")
    values: dict[str, Any] = {}
    for spec in specs:
        value = raw[spec.name]
        kind = spec.kind
        if kind == SCALAR:
            values[spec.name] = _decode_scalar(spec.primitive_name, value, path, spec.name)
            continue
        if kind == ARRAY:
            values[spec.name] = _decode_array_ref(spec, value, arrays, used, path)
            continue
        where = f"{path}.{spec.name}"
        if kind == MESSAGE:
            values[spec.name] = decode_fields(spec.nested_type, value, arrays, used, where)
        elif kind == MESSAGE_LIST:
            if type(value) is not list:
                raise DecodeError(f"{where} must be a list; got {type(value).__name__}")
            values[spec.name] = [decode_fields(spec.nested_type, item, arrays, used, f"{where}[{index}]")
                                 for index, item in enumerate(value)]
        else:  # SEQUENCE
            values[spec.name] = decode_sequence(spec, value, where)
    msg = cls(**values)
    try:
        msg.check_consistency()
    except ValueError as error:  # the error names the class; add where it sits when nested
        raise DecodeError(str(error) if path == type(msg).__name__ else f"{path}: {error}") from None
    return msg


def _decode_scalar(primitive: str, value: Any, path: str, name: str) -> Any:
    python_type, low, high = SCALAR_CHECKS[primitive]
    if type(value) is not python_type or (low is not None and not low <= value <= high):
        raise DecodeError(f"{path}.{name} must be {primitive}; got {type(value).__name__} {short_repr(value)}")
    return value


def decode_sequence(spec: FieldSpec, value: object, where: str) -> np.ndarray:
    if type(value) is not list or (spec.length is not None and len(value) != spec.length):
        length = spec.length if spec.length is not None else "any number of"
        raise DecodeError(f"{where} must be a list of {length} {spec.primitive}; got {short_repr(value)}")
    python_type, low, high = SCALAR_CHECKS[spec.primitive_name]
    for index, item in enumerate(value):
        if type(item) is not python_type or (low is not None and not low <= item <= high):
            raise DecodeError(f"{where}[{index}] must be {spec.primitive}; got {type(item).__name__} "
                              f"{short_repr(item)}")
    return np.array(value, dtype=spec.dtype)


def _decode_array_ref(spec: FieldSpec, value: object, arrays: list[np.ndarray], used: list[bool], path: str
                      ) -> np.ndarray:
    if type(value) is ArrayRef:  # fast path: a valid, unused reference to an array of the right dtype and rank
        index = value.index
        if index < len(arrays) and not used[index]:
            values = arrays[index]
            if values.dtype == spec.dtype and values.ndim == len(spec.axes):
                used[index] = True
                return values
    where = f"{path}.{spec.name}"
    if type(value) is not ArrayRef:
        raise DecodeError(f"{where} must be an array reference; got {type(value).__name__} {short_repr(value)}")
    index = value.index
    if index >= len(arrays):
        raise DecodeError(f"{where} refers to array {index}; the message has {len(arrays)} array(s)")
    if used[index]:
        raise DecodeError(f"{where} refers to array {index}, which another field already uses")
    values = arrays[index]
    if values.dtype != spec.dtype:
        raise DecodeError(f"{where} must have dtype {spec.primitive} ({spec.element_dtype.str}); "
                          f"got {values.dtype.str}")
    if values.ndim != len(spec.axes):
        raise DecodeError(f"{where} must have {len(spec.axes)} dimension(s) ({', '.join(spec.axes)}); "
                          f"got shape {values.shape}")
    return values
