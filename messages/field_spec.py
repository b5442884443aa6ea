"""How a message field is declared: the five field specifiers, the primitives and dtypes they allow.

A message type (:func:`dptpu.messages.schema.message`) declares every field with one of these specifiers; the
:class:`FieldSpec` each one carries is the schema the codec walks. The table of specifiers is in
:mod:`dptpu.messages.schema`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal, TypeVar, overload

import numpy as np

if TYPE_CHECKING:  # schema imports this module: the base class is named for the type checker only
    from .schema import Message

__all__ = [
    "FieldSpec",
    "scalar",
    "sequence",
    "nested",
    "nested_list",
    "array",
    "SCALAR",
    "SEQUENCE",
    "MESSAGE",
    "MESSAGE_LIST",
    "ARRAY",
    "INTEGER_RANGES",
    "SCALAR_PRIMITIVES",
    "ARRAY_DTYPES",
    "SPEC_KEY",
    "short_type_name",
]

# Field kinds.
SCALAR = "scalar"
SEQUENCE = "sequence"
MESSAGE = "message"
MESSAGE_LIST = "message_list"
ARRAY = "array"

#: Inclusive value range of each integer primitive.
INTEGER_RANGES = {
    "int8": (-(2**7), 2**7 - 1),
    "uint8": (0, 2**8 - 1),
    "int16": (-(2**15), 2**15 - 1),
    "uint16": (0, 2**16 - 1),
    "int32": (-(2**31), 2**31 - 1),
    "uint32": (0, 2**32 - 1),
    "int64": (-(2**63), 2**63 - 1),
    "uint64": (0, 2**64 - 1),
}
SCALAR_PRIMITIVES = ("bool", *INTEGER_RANGES, "float64", "string")

#: Bulk array element types (ROS 2 primitive name -> little-endian numpy dtype).
ARRAY_DTYPES = {
    "bool": np.dtype("|b1"),
    "int8": np.dtype("|i1"),
    "uint8": np.dtype("|u1"),
    "int16": np.dtype("<i2"),
    "uint16": np.dtype("<u2"),
    "int32": np.dtype("<i4"),
    "uint32": np.dtype("<u4"),
    "int64": np.dtype("<i8"),
    "uint64": np.dtype("<u8"),
    "float32": np.dtype("<f4"),
    "float64": np.dtype("<f8"),
}
_SCALAR_DEFAULTS = {"bool": False, "float64": 0.0, "string": "", **{name: 0 for name in INTEGER_RANGES}}
SPEC_KEY = "dptpu.messages.spec"

_IntegerPrimitive = Literal["int8", "uint8", "int16", "uint16", "int32", "uint32", "int64", "uint64"]
_MessageT = TypeVar("_MessageT", bound="Message")


@dataclass(frozen=True)
class FieldSpec:
    """The wire description of one message field.

    Attributes
    ----------
    name : str
        Field name (same as ROS 2 where the type is a ROS type).
    kind : {"scalar", "sequence", "message", "message_list", "array"}
        How the field travels (see the module docstring).
    primitive : str or None
        ROS 2 primitive name of a scalar, of a sequence's elements or of an array's elements.
    length : int or None
        Fixed length of a sequence (``float64[9]``), None for a variable-length one.
    message_type : type or None
        Class of a nested message or of the elements of a message list.
    axes : tuple of str
        Axis names of an array, e.g. ``("F", "H", "W")``; its ndim is ``len(axes)``.
    """

    name: str
    kind: str
    primitive: str | None = None
    length: int | None = None
    message_type: type[Message] | None = None
    axes: tuple[str, ...] = ()

    @property
    def dtype(self) -> np.dtype | None:
        """Numpy dtype of an array's or a sequence's elements (little-endian), else None."""
        if self.kind in (ARRAY, SEQUENCE):
            return ARRAY_DTYPES[self.primitive_name]
        return None

    @property
    def primitive_name(self) -> str:
        """The primitive of a scalar, sequence or array field; ValueError for a nested message field."""
        if self.primitive is None:
            raise ValueError(f"field {self.name!r} ({self.kind}) has no primitive")
        return self.primitive

    @property
    def element_dtype(self) -> np.dtype:
        """Numpy dtype of a sequence's or an array's elements; ValueError for another kind of field."""
        dtype = self.dtype
        if dtype is None:
            raise ValueError(f"field {self.name!r} ({self.kind}) has no element dtype")
        return dtype

    @property
    def nested_type(self) -> type[Message]:
        """Class of a nested message or of a message list's elements; ValueError for another kind of field."""
        if self.message_type is None:
            raise ValueError(f"field {self.name!r} ({self.kind}) nests no message")
        return self.message_type

    @property
    def ros_type(self) -> str:
        """The field's type in ROS 2 ``.msg`` syntax, e.g. ``uint32``, ``float64[9]``, ``std_msgs/Header``."""
        if self.kind == SCALAR:
            return self.primitive_name
        if self.kind == SEQUENCE:
            return f"{self.primitive}[{'' if self.length is None else self.length}]"
        if self.kind == ARRAY:
            return f"{self.primitive}[]"
        short = short_type_name(self.nested_type.TYPE_NAME)
        return short if self.kind == MESSAGE else f"{short}[]"


# The specifiers below return a dataclasses.Field that the message decorator turns into the field's default;
# like dataclasses.field, each is typed as returning the field's value, so that ``count: int = scalar("uint32")``
# is checked against its annotation and every field counts as having a default.


def _spec_field(spec: FieldSpec, **field_options: Any) -> Any:
    return dataclasses.field(metadata={SPEC_KEY: spec}, **field_options)


@overload
def scalar(primitive: Literal["bool"], default: bool | None = None) -> bool: ...
@overload
def scalar(primitive: _IntegerPrimitive, default: int | None = None) -> int: ...
@overload
def scalar(primitive: Literal["float64"], default: float | None = None) -> float: ...
@overload
def scalar(primitive: Literal["string"], default: str | None = None) -> str: ...
@overload
def scalar(primitive: str, default: object = None) -> Any: ...
def scalar(primitive: str, default: object = None) -> Any:
    """A scalar field: ``bool``, an integer type (``uint8`` ... ``int64``), ``float64`` or ``string``.

    ``default`` defaults to ``False``, ``0``, ``0.0`` or ``""`` as in ROS 2.
    """
    if primitive not in SCALAR_PRIMITIVES:
        raise ValueError(f"scalar primitive must be one of {', '.join(SCALAR_PRIMITIVES)}; got {primitive!r}")
    value = _SCALAR_DEFAULTS[primitive] if default is None else default
    return _spec_field(FieldSpec("", SCALAR, primitive=primitive), default=value)


def sequence(primitive: str, length: int | None = None) -> np.ndarray:
    """A short numeric sequence carried inline in the header, e.g. ``sequence("float64", 9)`` for a 3x3 K.

    The Python value is a 1-D ndarray of ``primitive``'s dtype (zeros of ``length``, or empty, by
    default); decoding gives a new writable array. For anything large use :func:`array`.
    """
    if primitive not in ARRAY_DTYPES:
        raise ValueError(f"sequence primitive must be one of {', '.join(ARRAY_DTYPES)}; got {primitive!r}")
    if length is not None and (not isinstance(length, int) or length < 1):
        raise ValueError(f"sequence length must be a positive int or None; got {length!r}")
    dtype = ARRAY_DTYPES[primitive]
    size = 0 if length is None else length
    return _spec_field(FieldSpec("", SEQUENCE, primitive=primitive, length=length),
                       default_factory=lambda: np.zeros(size, dtype))


def nested(message_type: type[_MessageT]) -> _MessageT:
    """A nested message field (default: ``message_type()``)."""
    return _spec_field(FieldSpec("", MESSAGE, message_type=message_type), default_factory=message_type)


def nested_list(message_type: type[_MessageT]) -> list[_MessageT]:
    """A variable-length list of nested messages (default: empty list)."""
    return _spec_field(FieldSpec("", MESSAGE_LIST, message_type=message_type), default_factory=list)


def array(primitive: str, axes: tuple[str, ...]) -> np.ndarray:
    """A bulk array sent as its own raw frame (zero-copy), e.g. ``array("float32", ("H", "W"))``.

    The default is an empty array of that dtype with ``len(axes)`` dimensions.
    """
    if primitive not in ARRAY_DTYPES:
        raise ValueError(f"array primitive must be one of {', '.join(ARRAY_DTYPES)}; got {primitive!r}")
    axes = tuple(axes)
    dtype = ARRAY_DTYPES[primitive]
    return _spec_field(FieldSpec("", ARRAY, primitive=primitive, axes=axes),
                       default_factory=lambda: np.zeros((0,) * len(axes), dtype))


def short_type_name(type_name: str) -> str:
    """``"std_msgs/msg/Header"`` -> ``"std_msgs/Header"`` (the form ``.msg`` files use)."""
    package, _, name = type_name.split("/")
    return f"{package}/{name}"
