"""How a message type declares its fields, and the ``Message`` base class every type shares.

A message type is a mutable dataclass (like an rclpy message: default-construct it, then assign fields)
whose every field is declared with one of five field specifiers (:mod:`.field_spec`). The specifiers are the
schema: the codec (:mod:`.encoder`, :mod:`.decoder`) walks them to encode and to check a received message, and
:func:`message_definition` turns them into ROS 2 ``.msg`` text.

========================  ==========================  ==================================================
specifier                 Python value                on the wire
========================  ==========================  ==================================================
``scalar("uint32")``      int / float / bool / str    a msgpack scalar in the header
``sequence("float64",9)`` 1-D ndarray (small)         a msgpack list in the header (copied on decode)
``nested(Header)``        a message                   a msgpack map in the header
``nested_list(PField)``   list of messages            a msgpack list of maps in the header
``array("float32",        ndarray with these axes     one raw frame, zero-copy both ways; decoded as a
("H", "W"))``                                         read-only view of the received frame
========================  ==========================  ==================================================

Scalar primitives use ROS 2 names: ``bool``, ``int8``, ``uint8``, ``int16``, ``uint16``, ``int32``,
``uint32``, ``int64``, ``uint64``, ``float64``, ``string``. Bulk arrays are little-endian ``bool``,
``int8`` ... ``uint64``, ``float32`` or ``float64``.

Example::

    @message("dptpu_msgs/msg/Example", version=1)
    class Example(Message):
        count: int = scalar("uint32")
        depth_m: np.ndarray = array("float32", ("H", "W"))
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar, TypeVar, dataclass_transform

import numpy as np

from .field_encoding import encode_fields
from .field_spec import (
    ARRAY,
    ARRAY_DTYPES,
    INTEGER_RANGES,
    MESSAGE,
    MESSAGE_LIST,
    SCALAR,
    SCALAR_PRIMITIVES,
    SEQUENCE,
    SPEC_KEY,
    FieldSpec,
    array,
    nested,
    nested_list,
    scalar,
    sequence,
    short_type_name,
)
from .registry import is_registered, register
from .wire_format import EncodeError

__all__ = [
    "Message",
    "FieldSpec",
    "message",
    "scalar",
    "sequence",
    "nested",
    "nested_list",
    "array",
    "message_definition",
    "SCALAR",
    "SEQUENCE",
    "MESSAGE",
    "MESSAGE_LIST",
    "ARRAY",
    "INTEGER_RANGES",
    "SCALAR_PRIMITIVES",
    "ARRAY_DTYPES",
]

_MessageClass = TypeVar("_MessageClass", bound="type[Message]")


# For a type checker every subclass is a dataclass (PEP 681, the base-class form), as each becomes one at run time
# through message(), applied by hand or by dptpu.graph.interfaces.service_type to a service's Request and Response.
# No field_specifiers: a type checker takes a specifier call for a field without a default unless the call spells
# default= or default_factory=, while every specifier here supplies one; the specifiers are typed as returning the
# field's value (like dataclasses.field), so each field reads as a field with a default of its annotated type.
@dataclass_transform(eq_default=False)
class Message:
    """Base class of every message type.

    Subclasses are made with :func:`message`. Equality compares every field, arrays bit-exactly
    (same dtype, shape and bytes); ``repr`` summarizes arrays by shape and dtype.
    """

    TYPE_NAME: ClassVar[str]
    SCHEMA_VERSION: ClassVar[int]
    FIELDS: ClassVar[tuple[FieldSpec, ...]]
    FIELD_NAMES: ClassVar[frozenset[str]]
    __dataclass_fields__: ClassVar[dict[str, dataclasses.Field[Any]]]  # set on each subclass by message()

    def check_consistency(self) -> None:
        """Check relations between fields (e.g. ``len(data) == step * height``); raise ValueError.

        Called by the codec on every message it encodes or decodes, after the field types were
        checked, so an override may rely on every field having its declared type. The base class
        checks nothing.
        """

    def validate(self) -> None:
        """Check field types and consistency, as encoding would; raise ValueError naming the field.

        Raises
        ------
        EncodeError
            The encoder's general path's error (:func:`dptpu.messages.field_encoding.encode_fields`), e.g.
            ``cannot encode sensor_msgs/msg/Image: Image.height must be uint32; got str 'x'``.
        """
        cls = type(self)
        if not is_registered(getattr(cls, "TYPE_NAME", None)):
            raise EncodeError(f"msg must be a registered message (e.g. sensor_msgs Image); got {cls.__name__}")
        try:
            encode_fields(self, cls.__name__, [])
        except EncodeError as error:
            raise EncodeError(f"cannot encode {cls.TYPE_NAME}: {error}") from None

    def __eq__(self, other: object) -> bool:
        if type(other) is not type(self):
            return NotImplemented
        return all(_values_equal(spec, getattr(self, spec.name), getattr(other, spec.name))
                   for spec in self.FIELDS)

    # Mutable, like rclpy messages. typeshed declares object.__hash__ a method, so "unhashable" (None, as Python
    # spells it) is not expressible as an override of it.
    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        parts = ", ".join(f"{spec.name}={_summary(getattr(self, spec.name))}" for spec in self.FIELDS)
        return f"{type(self).__name__}({parts})"


def _values_equal(spec: FieldSpec, a: Any, b: Any) -> bool:
    if spec.kind in (ARRAY, SEQUENCE):
        if spec.kind == SEQUENCE:
            a, b = np.asarray(a, spec.dtype), np.asarray(b, spec.dtype)
        if not (isinstance(a, np.ndarray) and isinstance(b, np.ndarray)):
            return False
        return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()
    if spec.kind == MESSAGE_LIST:
        return len(a) == len(b) and all(x == y for x, y in zip(a, b))
    return bool(a == b)


def _summary(value: object) -> str:
    if isinstance(value, np.ndarray) and value.size > 12:
        return f"<ndarray {value.shape} {value.dtype}>"
    return repr(value)


def message(type_name: str, *, version: int = 1) -> Callable[[_MessageClass], _MessageClass]:
    """Class decorator: make ``cls`` a message dataclass named ``type_name`` and register it.

    Parameters
    ----------
    type_name : str
        ``package/msg/Type``; ROS 2's name for a ROS type, ``dptpu_msgs/msg/...`` for ours.
    version : int
        Schema version (>= 1). Bump it whenever a field is added, removed, renamed or changes type
        or meaning, in this type or in any type it nests; peers with another version refuse the
        message (:class:`dptpu.messages.wire_format.DecodeError`).
    """
    if not isinstance(version, int) or isinstance(version, bool) or version < 1:
        raise ValueError(f"schema version must be an int >= 1; got {version!r}")

    def wrap(cls: _MessageClass) -> _MessageClass:
        if not issubclass(cls, Message):
            raise TypeError(f"{cls.__qualname__} must subclass Message")
        dataclass(eq=False, repr=False)(cls)  # in place: without slots the same class comes back
        specs: list[FieldSpec] = []
        for field in dataclasses.fields(cls):
            spec = field.metadata.get(SPEC_KEY)
            if spec is None:
                raise TypeError(f"{cls.__qualname__}.{field.name} must be declared with scalar(), sequence(), "
                                "nested(), nested_list() or array()")
            specs.append(dataclasses.replace(spec, name=field.name))
        cls.TYPE_NAME = type_name
        cls.SCHEMA_VERSION = version
        cls.FIELDS = tuple(specs)
        cls.FIELD_NAMES = frozenset(spec.name for spec in specs)
        register(type_name, cls)
        return cls

    return wrap


def message_definition(message_type: type[Message]) -> str:
    """ROS 2 ``.msg`` text of a message type followed by the types it nests (the ``ros2msg`` form).

    For the ROS types this reproduces the ROS 2 definitions' fields (constants and comments aside),
    which is what an MCAP ``ros2msg`` schema needs. Bulk arrays appear as ``type[]`` with their axes
    in a comment, e.g. ``float32[] phases  # shape (F, H, W), row-major``.

    Parameters
    ----------
    message_type : type
        A class made with :func:`message`.

    Returns
    -------
    str
        The main definition, then ``=`` * 80, ``MSG: package/Type`` and the definition of every
        nested type, depth-first, each once.
    """
    if not (isinstance(message_type, type) and issubclass(message_type, Message) and hasattr(message_type, "FIELDS")):
        raise ValueError(f"message_type must be a message class; got {message_type!r}")
    order: list[type[Message]] = []

    def visit(cls: type[Message]) -> None:
        for spec in cls.FIELDS:
            if spec.kind in (MESSAGE, MESSAGE_LIST) and spec.nested_type not in order:
                order.append(spec.nested_type)
                visit(spec.nested_type)

    visit(message_type)
    blocks = [_definition_body(message_type)]
    for cls in order:
        blocks.append("=" * 80 + f"\nMSG: {short_type_name(cls.TYPE_NAME)}\n" + _definition_body(cls))
    return "\n".join(blocks)


def _definition_body(cls: type[Message]) -> str:
    lines = []
    for spec in cls.FIELDS:
        line = f"{spec.ros_type} {spec.name}"
        if spec.kind == ARRAY and len(spec.axes) > 1:
            line += f"  # shape ({', '.join(spec.axes)}), row-major"
        lines.append(line)
    return "\n".join(lines)
