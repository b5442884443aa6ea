"""Byte layout of ``sensor_msgs/PointCloud2`` points: PointField lists <-> numpy structured dtypes.

A point is ``point_step`` bytes; field ``i`` holds ``count`` elements of ``datatype`` starting at byte
``offset`` of the point. A row of the cloud is ``row_step >= width * point_step`` bytes.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import DTypeLike

__all__ = ["FieldLayout", "PointFieldLike", "POINT_FIELD_DTYPES", "datatype_of", "structured_dtype",
           "point_field_names", "field_layouts"]

#: PointField datatype constant -> element dtype (little-endian; ``>`` when the cloud is big-endian).
POINT_FIELD_DTYPES: dict[int, np.dtype] = {
    1: np.dtype("i1"),  # INT8
    2: np.dtype("u1"),  # UINT8
    3: np.dtype("<i2"),  # INT16
    4: np.dtype("<u2"),  # UINT16
    5: np.dtype("<i4"),  # INT32
    6: np.dtype("<u4"),  # UINT32
    7: np.dtype("<f4"),  # FLOAT32
    8: np.dtype("<f8"),  # FLOAT64
}
_DATATYPE_OF_KIND_SIZE = {(dtype.kind, dtype.itemsize): code for code, dtype in POINT_FIELD_DTYPES.items()}


class PointFieldLike(Protocol):
    """What :func:`structured_dtype` reads of a field: a PointField message or a :class:`FieldLayout`."""

    @property
    def name(self) -> str: ...
    @property
    def offset(self) -> int: ...
    @property
    def datatype(self) -> int: ...
    @property
    def count(self) -> int: ...


@dataclass(frozen=True)
class FieldLayout:
    """One PointField as plain values: ``name``, byte ``offset`` in the point, ``datatype`` code, ``count``."""

    name: str
    offset: int
    datatype: int
    count: int


def datatype_of(dtype: DTypeLike) -> int:
    """PointField datatype code (1..8) of a numpy element dtype; ValueError if there is none."""
    element = np.dtype(dtype)
    code = _DATATYPE_OF_KIND_SIZE.get((element.kind, element.itemsize))
    if code is None:
        raise ValueError(f"no PointField datatype for dtype {element}; expected int8, uint8, int16, uint16, "
                         "int32, uint32, float32 or float64")
    return code


def structured_dtype(fields: Iterable[PointFieldLike], point_step: int, is_bigendian: bool) -> np.dtype:
    """The structured dtype of one point (itemsize ``point_step``) described by ``fields``.

    Parameters
    ----------
    fields : sequence of FieldLayout-like
        Objects with ``name``, ``offset`` (bytes), ``datatype`` (1..8) and ``count`` (>= 1).
    point_step : int
        Bytes per point.
    is_bigendian : bool
        Byte order of multi-byte fields.

    Returns
    -------
    numpy.dtype
        Fields at their offsets; a field with ``count > 1`` is a sub-array of shape ``(count,)``.

    Raises
    ------
    ValueError
        Empty or duplicate names, unknown datatype, ``count < 1``, or a field beyond ``point_step``.
    """
    names: list[str] = []
    formats: list[np.dtype] = []
    offsets: list[int] = []
    for index, field in enumerate(fields):
        name, offset, datatype, count = field.name, field.offset, field.datatype, field.count
        if not name:
            raise ValueError(f"PointField {index} has an empty name")
        if name in names:
            raise ValueError(f"PointField name {name!r} appears twice")
        if datatype not in POINT_FIELD_DTYPES:
            raise ValueError(f"PointField {name!r} has datatype {datatype}; expected 1 (INT8) .. 8 (FLOAT64)")
        if count < 1:
            raise ValueError(f"PointField {name!r} has count {count}; expected >= 1")
        element = POINT_FIELD_DTYPES[datatype]
        if is_bigendian:
            element = element.newbyteorder(">")
        end = offset + element.itemsize * count
        if end > point_step:
            raise ValueError(f"PointField {name!r} spans bytes [{offset}, {end}) of a point but point_step is "
                             f"{point_step}")
        names.append(name)
        formats.append(element if count == 1 else np.dtype((element, (count,))))
        offsets.append(offset)
    return np.dtype({"names": names, "formats": formats, "offsets": offsets, "itemsize": point_step})


def point_field_names(dtype: np.dtype) -> tuple[str, ...]:
    """The field names of a structured point dtype, in order; ValueError if it is not structured."""
    if dtype.names is None:
        raise _not_structured(dtype)
    return dtype.names


def field_layouts(dtype: np.dtype) -> tuple[list[FieldLayout], bool]:
    """PointFields of a structured point dtype, and whether its multi-byte fields are big-endian.

    Raises
    ------
    ValueError
        Not a structured dtype, a field type with no PointField datatype, a sub-array that is not 1-D,
        or fields of mixed byte order.
    """
    if dtype.names is None or dtype.fields is None:
        raise _not_structured(dtype)
    names, fields = dtype.names, dtype.fields
    layouts: list[FieldLayout] = []
    orders: set[bool] = set()
    for name in names:
        field_dtype, offset = fields[name][:2]
        count = 1
        if field_dtype.subdtype is not None:
            field_dtype, shape = field_dtype.subdtype
            if len(shape) != 1:
                raise ValueError(f"field {name!r} has sub-array shape {shape}; only 1-D (count,) is supported")
            count = shape[0]
        layouts.append(FieldLayout(name, offset, datatype_of(field_dtype), count))
        if field_dtype.itemsize > 1:
            orders.add(_is_big_endian(field_dtype))
    if len(orders) > 1:
        raise ValueError("point fields mix little- and big-endian byte orders; convert them to one order")
    return layouts, orders == {True}


def _not_structured(dtype: np.dtype) -> ValueError:
    return ValueError(f"points must have a structured dtype with named fields; got {dtype}")


def _is_big_endian(dtype: np.dtype) -> bool:
    return dtype.byteorder == ">" or (dtype.byteorder == "=" and np.little_endian is False)
