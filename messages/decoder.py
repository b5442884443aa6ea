"""Decoding: one ZeroMQ multipart message ``[topic, header, *arrays]`` -> ``(topic, message)``.

:func:`decode` returns arrays that are read-only views of the received frames (no copy). Decoding trusts
nothing: every limit of :class:`DecodeLimits`, the dtype allow-list, exact shapes and the schema of the declared
type are checked, and anything wrong raises :class:`DecodeError` (a ``ValueError``) naming the problem. A
well-formed message takes a fast path (:mod:`.fast_decoding`); anything else the general path
(:mod:`.frame_reading`, :mod:`.field_decoding`).
"""

from __future__ import annotations

from .codec_plan import PLANS, plan_for
from .decode_limits import DEFAULT_LIMITS, DecodeLimits
from .fast_decoding import decode_fast, decode_well_formed
from .field_decoding import decode_fields
from .frame_reading import array_view, decode_topic, frame_views, header_class, unpack_header
from .registry import is_registered, lookup
from .schema import Message
from .wire_format import DecodeError

__all__ = ["decode", "decode_checked"]


def decode(frames, *, expected_type=None, limits: DecodeLimits = DEFAULT_LIMITS):
    """Decode multipart frames ``[topic, header, *arrays]`` into ``(topic, message)``.

    Parameters
    ----------
    frames : list or tuple
        The received frames: ``bytes``, ``bytearray``, ``memoryview`` or ``zmq.Frame``-like objects with
        a ``.buffer``. Array frames are viewed, not copied: the returned arrays keep them alive.
    expected_type : type or str, optional
        A message class or type name (``"sensor_msgs/msg/Image"``); another type raises DecodeError.
    limits : DecodeLimits
        Upper bounds on frames, bytes, dimensions and elements.

    Returns
    -------
    topic : str
    msg : Message
        Bulk arrays are read-only numpy views of the array frames; inline sequences (e.g.
        ``CameraInfo.k``) are new writable arrays.

    Raises
    ------
    DecodeError
        Too many frames or bytes, a malformed topic or header, an unknown type, a schema version
        mismatch, a dtype outside :data:`ALLOWED_DTYPES`, a shape that does not match its frame's
        length exactly, missing, unknown or mistyped fields, or inconsistent fields. The message
        starts with the topic and type when they are known.
    ValueError
        ``expected_type`` or ``limits`` is not valid (a caller error, not a bad message).
    """
    if not isinstance(limits, DecodeLimits):
        raise ValueError(f"limits must be a DecodeLimits; got {type(limits).__name__}")
    expected = expected_type if expected_type in _EXPECTED_CLASSES else _expected_class(expected_type)
    decoded = decode_well_formed(frames, expected, limits)
    if decoded is not None:
        return decoded
    return _decode_general(frames, expected, limits)


def decode_checked(frames, *, expected_type=None, limits: DecodeLimits = DEFAULT_LIMITS):
    """:func:`decode` by the general path only: every limit and field checked one by one.

    The same result or the same :class:`DecodeError` as :func:`decode` (which first tries a one-pass fast
    path for well-formed messages); here for tests and ``dptpu bench codec``, which compare the two.
    """
    if not isinstance(limits, DecodeLimits):
        raise ValueError(f"limits must be a DecodeLimits; got {type(limits).__name__}")
    return _decode_general(frames, _expected_class(expected_type), limits)


def _decode_general(frames, expected, limits: DecodeLimits):
    """The general path: checks everything one by one and names the first problem."""
    topic: str | None = None
    cls: type[Message] | None = None
    try:
        views = frame_views(frames, limits)
        topic = decode_topic(views[0], limits)
        header = unpack_header(views[1], limits)
        cls = header_class(header, expected, len(views) - 2)
        arrays = [array_view(index, descriptor, view, limits)
                  for index, (descriptor, view) in enumerate(zip(header["arrays"], views[2:]))]
        plan = PLANS.get(cls) or plan_for(cls)
        msg = decode_fast(plan, header["fields"], arrays) if plan is not None and plan.fast is not None else None
        if msg is None:  # nested fields, or anything the fast path does not accept: check each one
            used = [False] * len(arrays)
            msg = decode_fields(cls, header["fields"], arrays, used, cls.__name__)
            if not all(used):
                raise DecodeError(f"array frame(s) {[i for i, u in enumerate(used) if not u]} are not referenced "
                                  "by any field")
    except DecodeError as error:
        context = "cannot decode message"
        if topic is not None:
            context += f" on topic {topic!r}"
        if cls is not None:
            context += f" of type {cls.TYPE_NAME}"
        raise DecodeError(f"{context}: {error}") from None
    return topic, msg


_EXPECTED_CLASSES: set = set()  # message classes already accepted as expected_type (registration is permanent)


def _expected_class(expected_type):
    if expected_type is None:
        return None
    if expected_type in _EXPECTED_CLASSES:
        return expected_type
    if isinstance(expected_type, str):
        try:
            return lookup(expected_type)
        except KeyError as error:
            raise ValueError(f"expected_type: {error.args[0]}") from None
    if isinstance(expected_type, type) and issubclass(expected_type, Message) \
            and is_registered(getattr(expected_type, "TYPE_NAME", None)):
        _EXPECTED_CLASSES.add(expected_type)
        return expected_type
    raise ValueError(f"expected_type must be a message class or type name; got {expected_type!r}")
