"""The codec's plan of each message class: what encoding and decoding need of it, worked out once per class."""

from __future__ import annotations

from typing import Any

import msgpack
import numpy as np

from .field_spec import ARRAY, MESSAGE, SCALAR, SEQUENCE
from .registry import is_registered
from .schema import Message
from .wire_format import SCALAR_CHECKS, WIRE_VERSION

__all__ = ["CodecPlan", "FastEntry", "plan_for", "PLANS", "SCALAR_FIELD", "ARRAY_FIELD", "MESSAGE_FIELD",
           "MESSAGE_LIST_FIELD", "SEQUENCE_FIELD"]

# Kinds of the fields in a plan's ``fast`` entries.
SCALAR_FIELD, ARRAY_FIELD, MESSAGE_FIELD, MESSAGE_LIST_FIELD, SEQUENCE_FIELD = range(5)

#: One field of a fast plan: ``(name, kind, python_type, low, high, dtype, ndim, extra)`` (see :class:`CodecPlan`);
#: ``extra`` is a str, a CodecPlan or a FieldSpec depending on ``kind``, hence Any (the fast paths read it unchecked).
FastEntry = tuple[str, int, "type[Any] | None", "int | None", "int | None", "np.dtype | None", int, Any]


class CodecPlan:
    """What the codec needs of one message class, worked out once per class (the schema is fixed).

    Attributes
    ----------
    cls : type
        The message class.
    prefix : bytes
        The packed header up to the value of ``"fields"``: a 5-entry msgpack map header, then
        ``"wire"``, ``"type"`` and ``"version"`` with their values and the key ``"fields"``. The
        header is ``prefix + packb(fields) + packb("arrays") + packb(descriptors)``, byte for byte what
        ``packb`` of the whole header map gives.
    fast : tuple or None
        One entry per field for the fast paths, ``(name, kind, python_type, low, high, dtype, ndim, extra)``:
        a scalar's exact Python type and inclusive integer range; an array's dtype, number of dimensions
        and wire dtype string (``extra``); a nested message's or a message list's element plan (``extra``);
        a sequence's FieldSpec (``extra``). None when a nested class has no fast plan (then every message
        of the class takes the general path).
    field_names : frozenset
        ``cls.FIELD_NAMES``: the keys of the class's field map.
    checks : bool
        Whether the class overrides ``Message.check_consistency`` (else calling it is skipped).
    """

    __slots__ = ("cls", "prefix", "fast", "field_names", "checks")

    def __init__(self, cls: type[Message]):
        header_start = {"wire": WIRE_VERSION, "type": cls.TYPE_NAME, "version": cls.SCHEMA_VERSION}
        packed = msgpack.packb(header_start, use_bin_type=True)
        # a 3-entry fixmap (0x83) becomes the 5-entry header (0x85); then the key "fields"
        self.prefix = b"\x85" + packed[1:] + msgpack.packb("fields", use_bin_type=True)
        self.cls = cls
        self.field_names = cls.FIELD_NAMES
        self.checks = getattr(cls, "check_consistency", None) is not Message.check_consistency
        self.fast: tuple[FastEntry, ...] | None = None

    def build_fast(self) -> None:
        """Fill :attr:`fast` (after the plan is in ``PLANS``, so a class that nests itself finds it, still
        without a fast plan, and takes the general path)."""
        entries: list[FastEntry] = []
        for spec in self.cls.FIELDS:
            kind = spec.kind
            if kind == SCALAR:
                python_type, low, high = SCALAR_CHECKS[spec.primitive_name]
                entries.append((spec.name, SCALAR_FIELD, python_type, low, high, None, 0, None))
            elif kind == ARRAY:
                dtype = spec.element_dtype
                entries.append((spec.name, ARRAY_FIELD, None, None, None, dtype, len(spec.axes), dtype.str))
            elif kind == SEQUENCE:
                entries.append((spec.name, SEQUENCE_FIELD, None, None, None, None, 0, spec))
            else:
                nested = plan_for(spec.nested_type)
                if nested is None or nested.fast is None:
                    return
                entries.append((spec.name, MESSAGE_FIELD if kind == MESSAGE else MESSAGE_LIST_FIELD,
                                None, None, None, None, 0, nested))
        self.fast = tuple(entries)


PLANS: dict[type, CodecPlan] = {}  # message class -> CodecPlan (registration is permanent, so is a plan)


def plan_for(cls: type) -> CodecPlan | None:
    """The class's plan, or None when ``cls`` is not a registered message class."""
    plan = PLANS.get(cls)
    if plan is None:
        if not (isinstance(cls, type) and issubclass(cls, Message) and is_registered(getattr(cls, "TYPE_NAME", None))):
            return None
        plan = PLANS[cls] = CodecPlan(cls)
        plan.build_fast()
    return plan
