"""Service types and the few plain messages the runtime itself needs (``std_srvs``-like, ``std_msgs/String``).

A service type is a class with nested ``Request`` and ``Response`` message classes, as rclpy's::

    @service_type("std_srvs/srv/SetBool")
    class SetBool:
        class Request(Message):
            data: bool = scalar("bool")

        class Response(Message):
            success: bool = scalar("bool")
            message: str = scalar("string")

:func:`service_type` registers ``Request`` and ``Response`` with the message codec as
``package/msg/<Name>Request`` and ``package/msg/<Name>Response`` (ROS 2 calls them
``package/srv/<Name>_Request``; the codec's registry only takes ``package/msg/Type`` names) and the
service itself under ``package/srv/<Name>`` (:func:`lookup_service`).
"""

from __future__ import annotations

import re

from ..messages.schema import Message, message, scalar

__all__ = ["service_type", "lookup_service", "registered_services", "is_service_type", "String", "Empty",
           "Trigger", "SetBool"]

_SERVICE_NAME = re.compile(r"^([a-z][a-z0-9_]*)/srv/([A-Z][A-Za-z0-9]*)$")
_SERVICES: dict[str, type] = {}


def service_type(type_name: str):
    """Class decorator: make ``cls`` (with nested ``Request`` and ``Response``) a service type.

    Parameters
    ----------
    type_name : str
        ``package/srv/Name``, e.g. ``"std_srvs/srv/Trigger"``.

    Raises
    ------
    ValueError
        For a malformed name, a name already used by another class, or missing ``Request``/``Response``.
    """
    match = _SERVICE_NAME.match(type_name) if isinstance(type_name, str) else None
    if match is None:
        raise ValueError(f"service type name must look like 'package/srv/Name'; got {type_name!r}")
    package, name = match.groups()

    def wrap(cls):
        existing = _SERVICES.get(type_name)
        if existing is not None and existing is not cls:
            raise ValueError(f"service type {type_name!r} is already registered to {existing.__qualname__}")
        for part in ("Request", "Response"):
            inner = getattr(cls, part, None)
            if not (isinstance(inner, type) and issubclass(inner, Message)):
                raise ValueError(f"service type {cls.__qualname__} needs a nested '{part}' class deriving from "
                                 "dptpu.messages.Message")
            if "TYPE_NAME" not in vars(inner):  # not decorated with @message yet
                setattr(cls, part, message(f"{package}/msg/{name}{part}")(inner))
        cls.TYPE_NAME = type_name
        _SERVICES[type_name] = cls
        return cls

    return wrap


def is_service_type(obj: object) -> bool:
    """True for a class made with :func:`service_type`."""
    type_name = getattr(obj, "TYPE_NAME", None)
    return isinstance(obj, type) and isinstance(type_name, str) and _SERVICES.get(type_name) is obj


def lookup_service(type_name: str) -> type:
    """The service class registered as ``type_name`` (e.g. ``"std_srvs/srv/Trigger"``); KeyError lists known ones."""
    try:
        return _SERVICES[type_name]
    except (KeyError, TypeError):
        raise KeyError(f"unknown service type {type_name!r}; known: {', '.join(sorted(_SERVICES))}") from None


def registered_services() -> dict[str, type]:
    """``{type_name: class}`` of every registered service type, sorted by name."""
    return {name: _SERVICES[name] for name in sorted(_SERVICES)}


# --------------------------------------------------------------------------------------------------
# std_msgs/msg/String
# --------------------------------------------------------------------------------------------------

@message("std_msgs/msg/String", version=1)
class String(Message):
    """A text message, ROS 2 ``std_msgs/msg/String`` (field ``data``)."""

    data: str = scalar("string")


# --------------------------------------------------------------------------------------------------
# std_srvs
# --------------------------------------------------------------------------------------------------

@service_type("std_srvs/srv/Empty")
class Empty:
    """No request data, no response data (``std_srvs/srv/Empty``)."""

    class Request(Message):
        pass

    class Response(Message):
        pass


@service_type("std_srvs/srv/Trigger")
class Trigger:
    """Trigger an action (``std_srvs/srv/Trigger``): Response ``success`` (bool), ``message`` (str)."""

    class Request(Message):
        pass

    class Response(Message):
        success: bool = scalar("bool")
        message: str = scalar("string")


@service_type("std_srvs/srv/SetBool")
class SetBool:
    """Switch something on or off (``std_srvs/srv/SetBool``): Request ``data``; Response ``success``, ``message``."""

    class Request(Message):
        data: bool = scalar("bool")

    class Response(Message):
        success: bool = scalar("bool")
        message: str = scalar("string")
