"""Build a message from YAML text, as ``ros2 service call SERVICE TYPE '{data: true}'`` does.

The YAML holds a mapping of field names to values (``{}`` or an empty string for all defaults);
nested messages are nested mappings, message lists are lists of mappings, sequences and arrays are
lists of numbers. Values are checked against the message's schema before anything is sent:

- ``bool`` fields take ``true``/``false`` only; integer fields take integers in their range (not
  bools, not floats); ``float64`` fields take integers or floats; ``string`` fields take strings;
- unknown field names are refused with the list of known fields;
- finally the codec's own check (``Message.validate``) runs, so a field relation such as
  ``Image.data`` holding ``step * height`` bytes is checked too.

Every problem raises ``ValueError`` naming the field path, e.g. ``SetBool.Request.data must be bool;
got int 3``.
"""

from __future__ import annotations

import numpy as np
import yaml

from dptpu.messages.schema import ARRAY, INTEGER_RANGES, MESSAGE, MESSAGE_LIST, SCALAR, SEQUENCE, Message

__all__ = ["message_from_yaml", "message_from_data"]


def message_from_yaml(message_type: type, text: str) -> Message:
    """A ``message_type`` filled from the YAML mapping in ``text``.

    Parameters
    ----------
    message_type : type
        A message class (e.g. ``SetBool.Request``).
    text : str
        YAML mapping of field values, e.g. ``"{data: true}"``; ``""`` or ``"{}"`` for defaults.

    Raises
    ------
    ValueError
        Text that is not YAML or not a mapping, unknown fields, values of the wrong type or range.
    """
    if not isinstance(text, str):
        raise ValueError(f"request values must be YAML text; got {type(text).__name__}")
    try:
        data = yaml.safe_load(text) if text.strip() else {}
    except yaml.YAMLError as exc:
        raise ValueError(f"request values are not valid YAML ({exc.__class__.__name__}): {text!r}") from None
    msg = message_from_data(message_type, {} if data is None else data)
    msg.validate()
    return msg


def _name(message_type: type) -> str:
    return message_type.__qualname__


def message_from_data(message_type: type, data, path: str | None = None) -> Message:
    """A ``message_type`` filled from a mapping of plain values (see the module docstring for the rules)."""
    if not (isinstance(message_type, type) and issubclass(message_type, Message) and hasattr(message_type, "FIELDS")):
        raise ValueError(f"message_type must be a message class; got {message_type!r}")
    path = path or _name(message_type)
    if not isinstance(data, dict):
        raise ValueError(f"{path} must be a mapping of field values, e.g. '{{field: value}}'; got "
                         f"{type(data).__name__} {data!r}")
    specs = {spec.name: spec for spec in message_type.FIELDS}
    unknown = [key for key in data if key not in specs]
    if unknown:
        known = ", ".join(specs) or "(none)"
        raise ValueError(f"{path} has no field(s) {', '.join(map(str, unknown))}; its fields: {known}")
    values = {}
    for name, value in data.items():
        spec = specs[name]
        where = f"{path}.{name}"
        if spec.kind == SCALAR:
            values[name] = _scalar(spec.primitive_name, value, where)
        elif spec.kind == MESSAGE:
            values[name] = message_from_data(spec.nested_type, value, where)
        elif spec.kind == MESSAGE_LIST:
            if not isinstance(value, list):
                raise ValueError(f"{where} must be a list of mappings; got {type(value).__name__}")
            values[name] = [message_from_data(spec.nested_type, item, f"{where}[{index}]")
                            for index, item in enumerate(value)]
        elif spec.kind == SEQUENCE:
            values[name] = _numbers(spec, value, where, ndim=1)
        elif spec.kind == ARRAY:
            values[name] = _numbers(spec, value, where, ndim=len(spec.axes))
    return message_type(**values)


def _scalar(primitive: str, value, where: str):
    if primitive == "bool":
        if isinstance(value, bool):
            return value
    elif primitive == "string":
        if isinstance(value, str):
            return value
    elif primitive == "float64":
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            return float(value)
    elif isinstance(value, int) and not isinstance(value, bool):
        low, high = INTEGER_RANGES[primitive]
        if low <= value <= high:
            return value
        raise ValueError(f"{where} must be {primitive} in [{low}, {high}]; got {value}")
    raise ValueError(f"{where} must be {primitive}; got {type(value).__name__} {value!r}")


def _numbers(spec, value, where: str, ndim: int) -> np.ndarray:
    if not isinstance(value, list):
        raise ValueError(f"{where} must be a list of {spec.primitive} values; got {type(value).__name__} {value!r}")
    try:
        values = np.asarray(value)
    except ValueError as exc:  # ragged nesting
        raise ValueError(f"{where} must be a rectangular list of {spec.primitive} values ({exc})") from None
    if values.size == 0:
        values = np.zeros((0,) * ndim, dtype=spec.dtype)
    if values.ndim != ndim:
        raise ValueError(f"{where} must have {ndim} dimension(s); got shape {values.shape}")
    target = spec.dtype
    kind = values.dtype.kind
    ok = (kind == "b") if target.kind == "b" else (kind in "iu" if target.kind in "iu" else kind in "iuf")
    if not ok:
        raise ValueError(f"{where} must hold {spec.primitive} values; got {values.dtype} values {value!r}")
    if target.kind in "iu" and values.size:
        low, high = INTEGER_RANGES[spec.primitive]
        if int(values.min()) < low or int(values.max()) > high:
            raise ValueError(f"{where} values must lie in [{low}, {high}] for {spec.primitive}; got "
                             f"[{int(values.min())}, {int(values.max())}]")
    return np.ascontiguousarray(values.astype(target))
