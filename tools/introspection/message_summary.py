"""Messages as plain data for ``dptpu topic echo`` and ``dptpu service call``, with arrays summarized.

A 7 MB image must not be dumped to a terminal: every bulk array (an ``array(...)`` field, one raw
frame on the wire) becomes an :class:`ArraySummary`, ``{dtype, shape, min, max, mean}``; inline
sequences (``sequence(...)`` fields such as ``CameraInfo.k``) are printed in full up to
``max_sequence_length`` values and summarized beyond. Everything else keeps the message's structure:
nested messages become dicts, message lists become lists, in field order.

Three renderings:

- :func:`message_to_yaml`: the ``ros2 topic echo`` layout (``field: value``, nested fields indented
  two spaces, list items as ``- ``), a summary as a one-line flow map
  ``data: {dtype: uint8, shape: [32], min: 7, max: 38, mean: 22.5}``;
- :func:`message_to_json`: one line of JSON (summaries are objects);
- :func:`message_repr`: the one-line form ``ros2 service call`` prints,
  ``std_srvs.srv.Trigger_Response(success=True, message='ok')``.

Convention: a summary's ``min``/``max``/``mean`` are over the finite values (NaN and +-inf are
counted in ``nonfinite``, present for float arrays only); they are None for an array with no finite
value. Bool arrays give ``min``/``max`` as bools and ``mean`` as the fraction of True.
"""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np
import yaml

from dptpu.graph.interfaces import registered_services
from dptpu.messages.schema import ARRAY, MESSAGE, MESSAGE_LIST, SEQUENCE, Message

__all__ = ["ArraySummary", "summarize_array", "message_to_dict", "message_to_yaml", "message_to_json",
           "message_repr", "DEFAULT_MAX_SEQUENCE_LENGTH"]

#: Inline sequences up to this many values are printed in full; longer ones are summarized.
DEFAULT_MAX_SEQUENCE_LENGTH = 16


class ArraySummary(dict):
    """``{"dtype", "shape", "min", "max", "mean"}`` (+ ``"nonfinite"`` for floats) standing for an array."""


def _python_number(value, kind: str):
    if kind == "b":
        return bool(value)
    if kind in "iu":
        return int(value)
    return float(value)


def summarize_array(values) -> ArraySummary:
    """Describe an array without its values.

    Parameters
    ----------
    values : ndarray
        Any shape; dtype bool, integer or float.

    Returns
    -------
    ArraySummary
        ``dtype`` (numpy name, e.g. ``"uint8"``), ``shape`` (list of int), ``min``, ``max``, ``mean``
        (Python numbers, None when there is no finite value) and, for float arrays, ``nonfinite``
        (count of NaN and +-inf).

    Raises
    ------
    ValueError
        ``values`` is not a numeric or bool ndarray.
    """
    if not isinstance(values, np.ndarray) or values.dtype.kind not in "biuf":
        raise ValueError(f"values must be a bool, integer or float ndarray; got "
                         f"{type(values).__name__} {getattr(values, 'dtype', '')}".rstrip())
    kind = values.dtype.kind
    summary = ArraySummary(dtype=values.dtype.name, shape=[int(size) for size in values.shape])
    flat = values.reshape(-1)
    if kind == "f":
        finite = np.isfinite(flat)  # (n,) bool
        nonfinite = int(flat.size - np.count_nonzero(finite))
        if nonfinite:
            flat = flat[finite]
    if flat.size:
        summary["min"] = _python_number(flat.min(), kind)
        summary["max"] = _python_number(flat.max(), kind)
        summary["mean"] = float(flat.mean(dtype=np.float64))
    else:
        summary["min"] = summary["max"] = summary["mean"] = None
    if kind == "f":
        summary["nonfinite"] = nonfinite
    return summary


def _sequence_value(values, max_sequence_length: int):
    values = np.asarray(values)
    if values.size > max_sequence_length:
        return summarize_array(values)
    kind = values.dtype.kind
    return [_python_number(v, kind) for v in values.reshape(-1)]


def message_to_dict(msg: Message, *, max_sequence_length: int = DEFAULT_MAX_SEQUENCE_LENGTH) -> dict:
    """The fields of ``msg`` as plain Python data, bulk arrays as :class:`ArraySummary`.

    Parameters
    ----------
    msg : Message
        Any message (made with ``dptpu.messages.schema.message``).
    max_sequence_length : int
        Inline sequences longer than this are summarized too (>= 0).

    Returns
    -------
    dict
        ``{field name: value}`` in field order; nested messages as dicts, message lists as lists.

    Raises
    ------
    ValueError
        ``msg`` is not a message, or ``max_sequence_length`` is negative.
    """
    if not isinstance(msg, Message) or not hasattr(type(msg), "FIELDS"):
        raise ValueError(f"msg must be a dptpu message; got {type(msg).__name__}")
    if isinstance(max_sequence_length, bool) or not isinstance(max_sequence_length, int) or max_sequence_length < 0:
        raise ValueError(f"max_sequence_length must be an int >= 0; got {max_sequence_length!r}")
    out: dict[str, Any] = {}
    for spec in type(msg).FIELDS:
        value = getattr(msg, spec.name)
        if spec.kind == ARRAY:
            out[spec.name] = summarize_array(np.asarray(value))
        elif spec.kind == SEQUENCE:
            out[spec.name] = _sequence_value(value, max_sequence_length)
        elif spec.kind == MESSAGE:
            out[spec.name] = message_to_dict(value, max_sequence_length=max_sequence_length)
        elif spec.kind == MESSAGE_LIST:
            out[spec.name] = [message_to_dict(item, max_sequence_length=max_sequence_length) for item in value]
        else:
            out[spec.name] = value
    return out


# --------------------------------------------------------------------------------------------------
# YAML (ros2 topic echo layout)
# --------------------------------------------------------------------------------------------------

def _yaml_scalar(value) -> str:
    if isinstance(value, float) and not math.isfinite(value):
        return ".nan" if math.isnan(value) else (".inf" if value > 0 else "-.inf")
    text = yaml.safe_dump(value, default_flow_style=True, width=float("inf"), allow_unicode=True)
    text = text.rstrip("\n")
    if text.endswith("\n..."):
        text = text[:-4]
    return text


def _yaml_flow(value) -> str:
    if isinstance(value, dict):
        return "{" + ", ".join(f"{key}: {_yaml_flow(item)}" for key, item in value.items()) + "}"
    if isinstance(value, list):
        return "[" + ", ".join(_yaml_flow(item) for item in value) + "]"
    return _yaml_scalar(value)


def _is_inline(value) -> bool:
    if isinstance(value, ArraySummary):
        return True
    if isinstance(value, dict):
        return not value
    if isinstance(value, list):
        return not any(isinstance(item, (dict, list)) for item in value)
    return True


def _yaml_lines(data: dict, indent: str) -> list[str]:
    lines = []
    for key, value in data.items():
        if _is_inline(value):
            lines.append(f"{indent}{key}: {_yaml_flow(value)}")
        elif isinstance(value, dict):
            lines.append(f"{indent}{key}:")
            lines.extend(_yaml_lines(value, indent + "  "))
        else:  # a list of messages (or of lists)
            lines.append(f"{indent}{key}:")
            for item in value:
                if isinstance(item, dict) and item and not isinstance(item, ArraySummary):
                    body = _yaml_lines(item, indent + "  ")
                    lines.append(f"{indent}- {body[0][len(indent) + 2:]}")
                    lines.extend(body[1:])
                else:
                    lines.append(f"{indent}- {_yaml_flow(item)}")
    return lines


def message_to_yaml(data: dict) -> str:
    """``ros2 topic echo``-style YAML of :func:`message_to_dict`'s output (no trailing ``---``).

    The text is valid YAML: ``yaml.safe_load`` gives back ``data`` (summaries as plain dicts).
    """
    if not isinstance(data, dict):
        raise ValueError(f"data must be the dict of message_to_dict; got {type(data).__name__}")
    return "\n".join(_yaml_lines(data, "")) if data else "{}"


# --------------------------------------------------------------------------------------------------
# JSON and repr
# --------------------------------------------------------------------------------------------------

def _json_safe(value):
    if isinstance(value, float) and not math.isfinite(value):
        return None if math.isnan(value) else ("inf" if value > 0 else "-inf")
    if isinstance(value, dict):
        return {key: _json_safe(item) for key, item in value.items()}
    if isinstance(value, list):
        return [_json_safe(item) for item in value]
    return value


def message_to_json(data: dict) -> str:
    """One line of strict JSON of :func:`message_to_dict`'s output (a NaN scalar becomes null)."""
    return json.dumps(_json_safe(data), separators=(", ", ": "), allow_nan=False)


def _type_path(type_name: str) -> str:
    """``"std_srvs/msg/TriggerResponse"`` -> ``"std_srvs.srv.Trigger_Response"``; messages -> ``pkg.msg.Type``."""
    package, kind, name = type_name.split("/")
    for suffix in ("Request", "Response"):
        if kind == "msg" and name.endswith(suffix) and len(name) > len(suffix):
            service = f"{package}/srv/{name[:-len(suffix)]}"
            if service in registered_services():
                return f"{package}.srv.{name[:-len(suffix)]}_{suffix}"
    return f"{package}.{kind}.{name}"


def _repr_value(value) -> str:
    if isinstance(value, ArraySummary):
        stats = " ".join(f"{key}={value[key]!r}" for key in ("min", "max", "mean") if key in value)
        return f"<{value['dtype']} array shape {tuple(value['shape'])} {stats}>"
    if isinstance(value, Message):
        return message_repr(value)
    if isinstance(value, list):
        return "[" + ", ".join(_repr_value(item) for item in value) + "]"
    return repr(value)


def message_repr(msg: Message, *, max_sequence_length: int = DEFAULT_MAX_SEQUENCE_LENGTH) -> str:
    """``package.kind.Type(field=value, ...)``: the one-line form ``ros2 service call`` prints.

    Bulk arrays (and sequences longer than ``max_sequence_length``) appear as
    ``<uint8 array shape (32,) min=7 max=38 mean=22.5>``.
    """
    if not isinstance(msg, Message) or not hasattr(type(msg), "FIELDS"):
        raise ValueError(f"msg must be a dptpu message; got {type(msg).__name__}")
    parts = []
    for spec in type(msg).FIELDS:
        value = getattr(msg, spec.name)
        if spec.kind == ARRAY:
            value = summarize_array(np.asarray(value))
        elif spec.kind == SEQUENCE:
            value = _sequence_value(value, max_sequence_length)
        parts.append(f"{spec.name}={_repr_value(value)}")
    return f"{_type_path(type(msg).TYPE_NAME)}({', '.join(parts)})"
