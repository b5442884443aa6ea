"""The encoder's general path: every field of a message checked, converted where allowed, or refused.

:func:`encode_fields` names the first field that is wrong (``Image.height``); :meth:`Message.validate` runs it,
and the encoder falls back to it whenever its fast path does not accept a message.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import msgpack
import numpy as np

from .field_spec import ARRAY, INTEGER_RANGES, MESSAGE, MESSAGE_LIST, SCALAR, FieldSpec
from .wire_format import ARRAY_INDEX, ARRAY_REF_EXT_CODE, SCALAR_CHECKS, EncodeError, short_repr

if TYPE_CHECKING:  # schema imports this module (Message.validate): the base class is named for the type checker only
    from .schema import Message

__all__ = ["encode_fields", "encode_sequence"]


def encode_fields(msg: Message, path: str, arrays: list[np.ndarray]) -> dict[str, Any]:
    """The header field map of ``msg`` (a message), appending its bulk arrays to ``arrays`` depth first in field
    order; raise :class:`EncodeError` naming the first wrong field, ``path`` being where ``msg`` sits
    (``Image``, ``PointCloud2.fields[0]``)."""
    out: dict[str, Any] = {}
    for spec in type(msg).FIELDS:
        value = getattr(msg, spec.name)
        kind = spec.kind
        if kind == SCALAR:
            python_type, low, high = SCALAR_CHECKS[spec.primitive_name]
            if type(value) is python_type and (low is None or low <= value <= high):
                out[spec.name] = value  # fast path: a builtin of the right type and range
            else:
                out[spec.name] = _encode_scalar(spec.primitive_name, value, f"{path}.{spec.name}")
            continue
        if kind == ARRAY:
            out[spec.name] = msgpack.ExtType(ARRAY_REF_EXT_CODE, ARRAY_INDEX.pack(len(arrays)))
            arrays.append(_encode_array(spec, value, path))
            continue
        where = f"{path}.{spec.name}"
        if kind == MESSAGE:
            _check_nested_type(spec, value, where)
            out[spec.name] = encode_fields(value, where, arrays)
        elif kind == MESSAGE_LIST:
            if not isinstance(value, (list, tuple)):
                raise EncodeError(f"{where} must be a list of {spec.nested_type.__name__}; got {type(value).__name__}")
            items = []
            for index, item in enumerate(value):
                _check_nested_type(spec, item, f"{where}[{index}]")
                items.append(encode_fields(item, f"{where}[{index}]", arrays))
            out[spec.name] = items
        else:  # SEQUENCE
            out[spec.name] = encode_sequence(spec, value, where)
    try:
        msg.check_consistency()
    except ValueError as error:  # the error names the class; add where it sits when nested
        raise EncodeError(str(error) if path == type(msg).__name__ else f"{path}: {error}") from None
    return out


def _check_nested_type(spec: FieldSpec, value: object, where: str) -> None:
    if type(value) is not spec.message_type:
        raise EncodeError(f"{where} must be a {spec.nested_type.__name__}; got {type(value).__name__}")


def _encode_scalar(primitive: str, value: object, where: str) -> str | bool | float | int:
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
                raise EncodeError(f"{where} is too large for float64; got {short_repr(value)}") from None
    elif isinstance(value, (int, np.integer)):
        number = int(value)
        low, high = INTEGER_RANGES[primitive]
        if low <= number <= high:
            return number
        raise EncodeError(f"{where} must be {primitive} in [{low}, {high}]; got {number}")
    raise EncodeError(f"{where} must be {primitive}; got {type(value).__name__} {short_repr(value)}")


def encode_sequence(spec: FieldSpec, value: object, where: str) -> list[Any]:
    try:
        values = np.asarray(value)
    except (ValueError, TypeError) as error:
        raise EncodeError(f"{where} must be a 1-D sequence of {spec.primitive}; got {short_repr(value)} "
                          f"({error})") from None
    expected = f"{spec.length}" if spec.length is not None else "n"
    if values.ndim != 1 or (spec.length is not None and values.shape[0] != spec.length):
        raise EncodeError(f"{where} must have shape ({expected},); got {values.shape}")
    kind = values.dtype.kind
    target = spec.element_dtype
    if target.kind == "f":
        ok = kind in "fiu"
    elif target.kind == "b":
        ok = kind == "b"
    else:
        ok = kind in "iu"
        if ok and values.size:
            low, high = INTEGER_RANGES[spec.primitive_name]
            ok = low <= int(values.min()) and int(values.max()) <= high
    if not ok:
        raise EncodeError(f"{where} must hold {spec.primitive} values; got dtype {values.dtype} {short_repr(value)}")
    return values.astype(target, copy=False).tolist()


def _encode_array(spec: FieldSpec, value: object, path: str) -> np.ndarray:
    target = spec.element_dtype
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
