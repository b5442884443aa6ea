"""The message type registry: wire type names such as ``"sensor_msgs/msg/Image"`` to classes.

Names follow ROS 2's ``package/msg/Type`` form: ROS types keep their ROS 2 name (``std_msgs/msg/Header``,
``sensor_msgs/msg/PointCloud2``), the scanner's own types live in ``dptpu_msgs/msg/...``. Every class
made with :func:`dptpu.messages.schema.message` registers itself at import; importing
:mod:`dptpu.messages` imports every message module, so the registry is complete once the package is
imported.
"""

from __future__ import annotations

import re
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # schema imports this module (message() registers): Message is named for the type checker only
    from .schema import Message

__all__ = ["register", "lookup", "registered_types", "is_registered"]

# ``package/msg/Type``: lower-case package, upper-camel type, as ROS 2 requires.
_TYPE_NAME = re.compile(r"^[a-z][a-z0-9_]*/msg/[A-Z][A-Za-z0-9]*$")

_TYPES: dict[str, type[Message]] = {}


def register(type_name: str, cls: type[Message]) -> None:
    """Register ``cls`` under ``type_name``.

    Parameters
    ----------
    type_name : str
        ROS 2 style name ``package/msg/Type``, e.g. ``"dptpu_msgs/msg/Trigger"``.
    cls : type
        The message class.

    Raises
    ------
    ValueError
        If the name is malformed or already taken by another class.
    """
    if not isinstance(type_name, str) or not _TYPE_NAME.match(type_name):
        raise ValueError(f"message type name must look like 'package/msg/Type'; got {type_name!r}")
    existing = _TYPES.get(type_name)
    if existing is not None and existing is not cls:
        raise ValueError(
            f"message type name {type_name!r} is already registered to "
            f"{existing.__module__}.{existing.__qualname__}; got {cls.__module__}.{cls.__qualname__}")
    _TYPES[type_name] = cls


def lookup(type_name: str) -> type[Message]:
    """The class registered under ``type_name``.

    Raises
    ------
    KeyError
        If no class has that name; the message lists the known names.
    """
    try:
        return _TYPES[type_name]
    except (KeyError, TypeError):
        raise KeyError(f"unknown message type {type_name!r}; known types: {', '.join(sorted(_TYPES))}") from None


def is_registered(type_name: object) -> bool:
    """True when ``type_name`` is a registered message type name."""
    return isinstance(type_name, str) and type_name in _TYPES


def registered_types() -> dict[str, type[Message]]:
    """A copy of the registry, ``{type_name: class}``, sorted by name."""
    return {name: _TYPES[name] for name in sorted(_TYPES)}
