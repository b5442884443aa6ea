"""How a message type declares its fields, and the ``Message`` base class every type shares.

A message type is a mutable dataclass (like an rclpy message: default-construct it, then assign fields)
whose every field is declared with one of five field specifiers. The specifiers are the schema: the
codec (:mod:`dptpu.messages.codec`) walks them to encode and to check a received message, and
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
from dataclasses import dataclass
from typing import ClassVar, dataclass_transform

import numpy as np

from .registry import register

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
_SPEC_KEY = "dptpu.messages.spec"


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
    message_type: type | None = None
    axes: tuple[str, ...] = ()

    @property
    def dtype(self) -> np.dtype | None:
        """Numpy dtype of an array's or a sequence's elements (little-endian), else None."""
        if self.kind in (ARRAY, SEQUENCE):
            return ARRAY_DTYPES[self.primitive]
        return None

    @property
    def ros_type(self) -> str:
        """The field's type in ROS 2 ``.msg`` syntax, e.g. ``uint32``, ``float64[9]``, ``std_msgs/Header``."""
        if self.kind == SCALAR:
            return self.primitive
        if self.kind == SEQUENCE:
            return f"{self.primitive}[{'' if self.length is None else self.length}]"
        if self.kind == ARRAY:
            return f"{self.primitive}[]"
        short = _short_type_name(self.message_type.TYPE_NAME)
        return short if self.kind == MESSAGE else f"{short}[]"


def _spec_field(spec: FieldSpec, **field_options):
    return dataclasses.field(metadata={_SPEC_KEY: spec}, **field_options)


def scalar(primitive: str, default=None):
    """A scalar field: ``bool``, an integer type (``uint8`` ... ``int64``), ``float64`` or ``string``.

    ``default`` defaults to ``False``, ``0``, ``0.0`` or ``""`` as in ROS 2.
    """
    if primitive not in SCALAR_PRIMITIVES:
        raise ValueError(f"scalar primitive must be one of {', '.join(SCALAR_PRIMITIVES)}; got {primitive!r}")
    value = _SCALAR_DEFAULTS[primitive] if default is None else default
    return _spec_field(FieldSpec("", SCALAR, primitive=primitive), default=value)


def sequence(primitive: str, length: int | None = None):
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


def nested(message_type: type):
    """A nested message field (default: ``message_type()``)."""
    return _spec_field(FieldSpec("", MESSAGE, message_type=message_type), default_factory=message_type)


def nested_list(message_type: type):
    """A variable-length list of nested messages (default: empty list)."""
    return _spec_field(FieldSpec("", MESSAGE_LIST, message_type=message_type), default_factory=list)


def array(primitive: str, axes: tuple[str, ...]):
    """A bulk array sent as its own raw frame (zero-copy), e.g. ``array("float32", ("H", "W"))``.

    The default is an empty array of that dtype with ``len(axes)`` dimensions.
    """
    if primitive not in ARRAY_DTYPES:
        raise ValueError(f"array primitive must be one of {', '.join(ARRAY_DTYPES)}; got {primitive!r}")
    axes = tuple(axes)
    dtype = ARRAY_DTYPES[primitive]
    return _spec_field(FieldSpec("", ARRAY, primitive=primitive, axes=axes),
                       default_factory=lambda: np.zeros((0,) * len(axes), dtype))


class Message:
    """Base class of every message type.

    Subclasses are made with :func:`message`. Equality compares every field, arrays bit-exactly
    (same dtype, shape and bytes); ``repr`` summarizes arrays by shape and dtype.
    """

    TYPE_NAME: ClassVar[str]
    SCHEMA_VERSION: ClassVar[int]
    FIELDS: ClassVar[tuple[FieldSpec, ...]]
    FIELD_NAMES: ClassVar[frozenset[str]]

    def check_consistency(self) -> None:
        """Check relations between fields (e.g. ``len(data) == step * height``); raise ValueError.

        Called by the codec on every message it encodes or decodes, after the field types were
        checked, so an override may rely on every field having its declared type. The base class
        checks nothing.
        """

    def validate(self) -> None:
        """Check field types and consistency, as encoding would; raise ValueError naming the field."""
        from .codec import encode  # deferred: codec imports this module

        encode("/validate", self)

    def __eq__(self, other) -> bool:
        if type(other) is not type(self):
            return NotImplemented
        return all(_values_equal(spec, getattr(self, spec.name), getattr(other, spec.name))
                   for spec in self.FIELDS)

    __hash__ = None  # mutable, like rclpy messages

    def __repr__(self) -> str:
        parts = ", ".join(f"{spec.name}={_summary(getattr(self, spec.name))}" for spec in self.FIELDS)
        return f"{type(self).__name__}({parts})"


def _values_equal(spec: FieldSpec, a, b) -> bool:
    if spec.kind in (ARRAY, SEQUENCE):
        if spec.kind == SEQUENCE:
            a, b = np.asarray(a, spec.dtype), np.asarray(b, spec.dtype)
        if not (isinstance(a, np.ndarray) and isinstance(b, np.ndarray)):
            return False
        return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()
    if spec.kind == MESSAGE_LIST:
        return len(a) == len(b) and all(x == y for x, y in zip(a, b))
    return bool(a == b)


def _summary(value) -> str:
    if isinstance(value, np.ndarray) and value.size > 12:
        return f"<ndarray {value.shape} {value.dtype}>"
    return repr(value)


def _short_type_name(type_name: str) -> str:
    """``"std_msgs/msg/Header"`` -> ``"std_msgs/Header"`` (the form ``.msg`` files use)."""
    package, _, name = type_name.split("/")
    return f"{package}/{name}"


@dataclass_transform(field_specifiers=(scalar, sequence, nested, nested_list, array))
def message(type_name: str, *, version: int = 1):
    """Class decorator: make ``cls`` a message dataclass named ``type_name`` and register it.

    Parameters
    ----------
    type_name : str
        ``package/msg/Type``; ROS 2's name for a ROS type, ``dptpu_msgs/msg/...`` for ours.
    version : int
        Schema version (>= 1). Bump it whenever a field is added, removed, renamed or changes type
        or meaning, in this type or in any type it nests; peers with another version refuse the
        message (:class:`dptpu.messages.codec.DecodeError`).
    """
    if not isinstance(version, int) or isinstance(version, bool) or version < 1:
        raise ValueError(f"schema version must be an int >= 1; got {version!r}")

    def wrap(cls):
        if not issubclass(cls, Message):
            raise TypeError(f"{cls.__qualname__} must subclass Message")
        cls = dataclass(eq=False, repr=False)(cls)
        specs = []
        for field in dataclasses.fields(cls):
            spec = field.metadata.get(_SPEC_KEY)
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


def message_definition(message_type: type) -> str:
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
    order: list[type] = []

    def visit(cls):
        for spec in cls.FIELDS:
            if spec.kind in (MESSAGE, MESSAGE_LIST) and spec.message_type not in order:
                order.append(spec.message_type)
                visit(spec.message_type)

    visit(message_type)
    blocks = [_definition_body(message_type)]
    for cls in order:
        blocks.append("=" * 80 + f"\nMSG: {_short_type_name(cls.TYPE_NAME)}\n" + _definition_body(cls))
    return "\n".join(blocks)


def _definition_body(cls: type) -> str:
    lines = []
    for spec in cls.FIELDS:
        line = f"{spec.ros_type} {spec.name}"
        if spec.kind == ARRAY and len(spec.axes) > 1:
            line += f"  # shape ({', '.join(spec.axes)}), row-major"
        lines.append(line)
    return "\n".join(lines)

