"""Every message type as a ROS 2 ``.msg`` definition: the ROS types as ROS 2 defines them, the scanner's own
(``dptpu_msgs``) in a form a ROS 2 package can build.

A ``.msg`` sequence has no shape, so a scanner type's multi-dimensional arrays travel flat (row-major) with the
image size as two fields of their own, ``uint32 height`` and ``uint32 width``, placed just before the first such
array (as ``sensor_msgs/Image`` carries its size); every other axis follows from the array's length (``F`` of
``PhaseMaps.phases``, ``(F, height, width)``, is ``len(phases) / (height * width)``). A type whose arrays are all
1-D is its fields exactly. :func:`ros2_fields` lists the fields of that form, :func:`ros2_message_definition`
gives the ``ros2msg`` schema text (the definition, then ``=`` * 80 and ``MSG: package/Type`` blocks of the nested
types, as rosbag2 writes it, with ROS 2's constants), :func:`ros2_msg_file` one type's ``.msg`` file with its
comments. The scanner's files ship as package data in ``dptpu/messages/msg/`` (``tests/messages`` checks they are
what this module makes), so a ROS 2 workspace builds a ``dptpu_msgs`` package from them and ``ros2 bag`` and
Foxglove read the scanner's channels of an MCAP recording.
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib import resources

from .field_spec import ARRAY, MESSAGE, MESSAGE_LIST, FieldSpec, short_type_name
from .schema import Message
from .sensor import PointField

__all__ = ["SHAPE_FIELDS", "Ros2Field", "msg_files", "ros2_fields", "ros2_message_definition", "ros2_msg_file",
           "shipped_msg_file"]

#: The fields that carry a scanner type's image size in its ROS 2 form (axes ``H`` and ``W``).
SHAPE_FIELDS = {"H": "height", "W": "width"}
#: Constants ROS 2 declares in its definitions (the codec's schema has fields only), ``.msg`` syntax.
_CONSTANTS = {
    "sensor_msgs/msg/PointField": [f"uint8 {name}={getattr(PointField, name)}"
                                   for name in ("INT8", "UINT8", "INT16", "UINT16", "INT32", "UINT32", "FLOAT32",
                                                "FLOAT64")],
    "diagnostic_msgs/msg/DiagnosticStatus": ["byte OK=0", "byte WARN=1", "byte ERROR=2", "byte STALE=3"],
    "dptpu_msgs/msg/ScanStatus": ["uint8 OK=0", "uint8 WARN=1", "uint8 ERROR=2", "uint8 STALE=3"],
}
#: ROS 2's own spelling of a field where it differs from the codec's primitive (``byte`` is one byte, as uint8).
_ROS_SPELLING = {("diagnostic_msgs/msg/DiagnosticStatus", "level"): "byte"}


@dataclass(frozen=True)
class Ros2Field:
    """One field of a type's ROS 2 form.

    Attributes
    ----------
    name : str
    ros_type : str
        In ``.msg`` syntax (``uint32``, ``float32[]``, ``std_msgs/Header``).
    spec : FieldSpec or None
        The codec's field; None for an added size field (``height``, ``width``).
    shape : tuple of str
        For a flattened array: its axes in ROS names (``("F", "height", "width")``).
    """

    name: str
    ros_type: str
    spec: FieldSpec | None = None
    shape: tuple[str, ...] = ()


def ros2_fields(cls: type[Message]) -> tuple[Ros2Field, ...]:
    """The fields of ``cls``'s ROS 2 form, in order (see the module docstring).

    Raises
    ------
    ValueError
        A type whose multi-dimensional arrays have axes the form cannot carry (more than one axis besides ``H``
        and ``W``), or a name clash with the added size fields.
    """
    _check_message_class(cls)
    cached = _FIELDS_CACHE.get(cls)
    if cached is not None:
        return cached
    fields: list[Ros2Field] = []
    sizes_added = False
    names = {spec.name for spec in cls.FIELDS}
    for spec in cls.FIELDS:
        ros_type = _ROS_SPELLING.get((cls.TYPE_NAME, spec.name), spec.ros_type)
        if spec.kind == ARRAY and len(spec.axes) > 1:
            others = [axis for axis in spec.axes if axis not in SHAPE_FIELDS]
            if len(others) > 1 or not set(SHAPE_FIELDS) & set(spec.axes):
                raise ValueError(f"{cls.TYPE_NAME}.{spec.name} has axes {spec.axes}: the ROS 2 form carries H and W "
                                 "as fields and at most one more axis, from the array's length")
            if not sizes_added:
                clash = names & set(SHAPE_FIELDS.values())
                if clash:
                    raise ValueError(f"{cls.TYPE_NAME} has a field {sorted(clash)[0]!r}, the name of a size field "
                                     "of its ROS 2 form")
                fields += [Ros2Field(SHAPE_FIELDS["H"], "uint32"), Ros2Field(SHAPE_FIELDS["W"], "uint32")]
                sizes_added = True
            shape = tuple(SHAPE_FIELDS.get(axis, axis) for axis in spec.axes)
            fields.append(Ros2Field(spec.name, ros_type, spec, shape))
        else:
            fields.append(Ros2Field(spec.name, ros_type, spec))
    result = tuple(fields)
    _FIELDS_CACHE[cls] = result
    return result


_FIELDS_CACHE: dict[type, tuple[Ros2Field, ...]] = {}


def ros2_message_definition(cls: type[Message]) -> str:
    """The ``ros2msg`` schema text of ``cls``: its ROS 2 form, then each nested type's (depth-first, once each).

    Blocks are separated by a line of 80 ``=`` and a ``MSG: package/Type`` line, as rosbag2 writes them; ROS 2's
    constants come first in their type's block; no comments.
    """
    _check_message_class(cls)
    order: list[type[Message]] = []

    def visit(owner: type[Message]) -> None:
        for spec in owner.FIELDS:
            if spec.kind in (MESSAGE, MESSAGE_LIST) and spec.nested_type not in order:
                order.append(spec.nested_type)
                visit(spec.nested_type)

    visit(cls)
    blocks = [_body(cls, comments=False)]
    for nested in order:
        blocks.append("=" * 80 + f"\nMSG: {short_type_name(nested.TYPE_NAME)}\n" + _body(nested, comments=False))
    return "\n".join(blocks)


def ros2_msg_file(cls: type[Message]) -> str:
    """The ``.msg`` file of ``cls`` (its ROS 2 form with constants and comments), e.g. ``PhaseMaps.msg``."""
    _check_message_class(cls)
    doc = (cls.__doc__ or "").strip().splitlines()
    head = f"# {cls.TYPE_NAME}: {doc[0]}\n" if doc else f"# {cls.TYPE_NAME}\n"
    head += f"# The ROS 2 form of dptpu's {cls.__name__} (dptpu.messages.ros2_definitions; made, not edited).\n"
    return head + _body(cls, comments=True) + "\n"


def msg_files() -> dict[str, str]:
    """``{file name: text}`` of every scanner type's ``.msg`` file (``dptpu_msgs``), as shipped."""
    from .registry import registered_types  # the registry fills as the type modules are imported

    return {f"{name.rsplit('/', 1)[1]}.msg": ros2_msg_file(cls) for name, cls in sorted(registered_types().items())
            if name.startswith("dptpu_msgs/") and cls.__module__.startswith("dptpu.messages")}


def shipped_msg_file(name: str) -> str:
    """The text of the shipped ``dptpu/messages/msg/<name>`` file (package data)."""
    return resources.files("dptpu.messages").joinpath("msg", name).read_text(encoding="utf-8")


def _body(cls: type[Message], *, comments: bool) -> str:
    lines = list(_CONSTANTS.get(cls.TYPE_NAME, []))
    for field in ros2_fields(cls):
        line = f"{field.ros_type} {field.name}"
        if comments and field.spec is None:
            line += "  # of every flattened array below"
        elif comments and field.shape:
            line += f"  # shape ({', '.join(field.shape)}), row-major"
        lines.append(line)
    return "\n".join(lines)


def _check_message_class(cls) -> None:
    if not (isinstance(cls, type) and issubclass(cls, Message) and hasattr(cls, "FIELDS")):
        raise ValueError(f"expected a message class; got {cls!r}")

