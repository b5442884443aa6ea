"""Node parameters: the :class:`Parameter` value type and the per-node store behind ``declare_parameter``.

Semantics follow rclpy (Humble and later):

- Parameters are statically typed: the declared value (or ``Parameter.Type``) fixes the type, and a
  value of another type is refused (``1`` is an INTEGER, so a DOUBLE parameter needs ``1.0``), unless
  the descriptor sets ``dynamic_typing``. A parameter declared with ``None`` has no type yet and takes
  the type of the first value it gets. An empty list fits every array type.
- Overrides (``--params-file``, ``-p``, ``parameter_overrides=``) replace the declared default at
  declaration; the type check applies to them and the error names where the value came from.
- ``set_parameters`` checks read-only, type and range, then asks every on-set callback
  (``add_on_set_parameters_callback``); a refusal leaves the value unchanged and comes back as
  ``SetParametersResult(successful=False, reason=...)``. Once the values are stored, every post-set callback
  (``add_post_set_parameters_callback``, rclpy Jazzy) gets the parameters that were set, to apply them; unlike
  Jazzy, a declaration does not call the post-set callbacks (the node reads the declared value itself).
  Undeclared names raise :class:`ParameterNotDeclaredException` unless the node allows undeclared parameters.
"""

from __future__ import annotations

import array
import builtins
import math
import re
import threading
from enum import IntEnum

import numpy as np

from .exceptions import (
    InvalidParameterException,
    InvalidParameterTypeException,
    InvalidParameterValueException,
    ParameterAlreadyDeclaredException,
    ParameterImmutableException,
    ParameterNotDeclaredException,
    ParameterUninitializedException,
)
from .rcl_interfaces import (
    FloatingPointRange,
    IntegerRange,
    ListParametersResult,
    ParameterDescriptor,
    ParameterValue,
    SetParametersResult,
    strings,
    texts,
)
from .rcl_interfaces import Parameter as ParameterMsg

__all__ = ["Parameter", "NodeParameters", "parameter_value_to_python", "validate_parameter_name",
           "ParameterDescriptor", "SetParametersResult", "FloatingPointRange", "IntegerRange"]

_NAME = re.compile(r"^[A-Za-z0-9_~/-]+(\.[A-Za-z0-9_~/-]+)*$")


def validate_parameter_name(name) -> str:
    """Return ``name`` if it is a valid parameter name (dot-separated tokens), else raise."""
    if not isinstance(name, str) or not name:
        raise InvalidParameterException(name, "must be a non-empty str")
    if not _NAME.match(name):
        raise InvalidParameterException(name)
    return name


def _is_bool(v) -> bool:
    return isinstance(v, (bool, np.bool_))


def _is_int(v) -> bool:
    return isinstance(v, (int, np.integer)) and not _is_bool(v)


def _is_float(v) -> bool:
    return isinstance(v, (float, np.floating))


class Parameter:
    """A named, typed value: ``Parameter(name, type_=None, value=None)`` as rclpy.

    Write ``Parameter("rate_hz", value=10.0)`` (the type follows the value) or
    ``Parameter("rate_hz", Parameter.Type.DOUBLE, 10.0)``. Values are normalized: numpy scalars
    become Python numbers, sequences become lists, byte arrays become ``bytes``.
    """

    class Type(IntEnum):
        NOT_SET = 0
        BOOL = 1
        INTEGER = 2
        DOUBLE = 3
        STRING = 4
        BYTE_ARRAY = 5
        BOOL_ARRAY = 6
        INTEGER_ARRAY = 7
        DOUBLE_ARRAY = 8
        STRING_ARRAY = 9

        @classmethod
        def from_parameter_value(cls, value) -> Parameter.Type:
            """The type a Python value has as a parameter; ValueError when it has none."""
            if value is None:
                return cls.NOT_SET
            if _is_bool(value):
                return cls.BOOL
            if _is_int(value):
                return cls.INTEGER
            if _is_float(value):
                return cls.DOUBLE
            if isinstance(value, str):
                return cls.STRING
            if isinstance(value, (bytes, bytearray)):
                return cls.BYTE_ARRAY
            if isinstance(value, np.ndarray):
                if value.ndim != 1:
                    raise InvalidParameterValueException("?", value, "array values must be 1-D")
                value = value.tolist()
            if isinstance(value, (list, tuple, array.array)):
                items = list(value)
                if not items:
                    return cls.BYTE_ARRAY  # rclpy's choice for an empty list; fits any array type here
                for kind, test in ((cls.BYTE_ARRAY, lambda v: isinstance(v, bytes) and len(v) == 1),
                                   (cls.BOOL_ARRAY, _is_bool), (cls.INTEGER_ARRAY, _is_int),
                                   (cls.DOUBLE_ARRAY, _is_float), (cls.STRING_ARRAY, lambda v: isinstance(v, str))):
                    if all(test(v) for v in items):
                        return kind
                raise InvalidParameterValueException(
                    "?", value, "a list parameter must hold values of one type: all bool, all int, all float "
                                "(write 1.0, not 1) or all str")
            raise InvalidParameterValueException(
                "?", value, f"type {type(value).__name__} is not a parameter type (bool, int, float, str, bytes "
                            "or a list of one of them)")

        def check(self, value) -> bool:
            """Whether ``value`` has this type (an empty sequence fits every array type)."""
            try:
                actual = Parameter.Type.from_parameter_value(value)
            except InvalidParameterValueException:
                return False
            if actual == self:
                return True
            return self.is_array and actual.is_array and _is_empty(value)

        @property
        def is_array(self) -> bool:
            return self >= Parameter.Type.BYTE_ARRAY

    def __init__(self, name, type_=None, value=None):
        if not isinstance(name, str):
            raise InvalidParameterException(name, "must be a str")
        if type_ is None:
            try:
                type_ = Parameter.Type.from_parameter_value(value)
            except InvalidParameterValueException as exc:
                raise InvalidParameterValueException(name, value, exc.args[0].split(": ", 1)[-1]) from None
        elif not isinstance(type_, Parameter.Type):
            raise InvalidParameterValueException(
                name, type_, "the second argument is the type (a Parameter.Type); pass the value by keyword: "
                             f"Parameter({name!r}, value={type_!r})")
        elif not type_.check(value):
            raise InvalidParameterValueException(name, value, f"it is not of type {type_.name}")
        self._name = name
        self._type = type_
        self._value = _normalize(type_, value)

    @property
    def name(self) -> str:
        return self._name

    @property
    def type_(self) -> Parameter.Type:
        return self._type

    @property
    def value(self):
        return self._value

    def get_descriptor(self) -> ParameterDescriptor:
        return ParameterDescriptor(name=self._name, type=int(self._type))

    def get_parameter_value(self) -> ParameterValue:
        """The value as an ``rcl_interfaces/msg/ParameterValue`` message."""
        return python_to_parameter_value(self._type, self._value)

    def to_parameter_msg(self) -> ParameterMsg:
        return ParameterMsg(name=self._name, value=self.get_parameter_value())

    @classmethod
    def from_parameter_msg(cls, msg: ParameterMsg) -> Parameter:
        return cls(msg.name, Parameter.Type(msg.value.type), parameter_value_to_python(msg.value))

    def __eq__(self, other):
        if not isinstance(other, Parameter):
            return NotImplemented
        return (self._name, self._type, self._value) == (other._name, other._type, other._value)

    # mutable; typeshed declares object.__hash__ a method, so "unhashable" (None) is not expressible as its override
    __hash__ = None  # type: ignore[assignment]

    def __repr__(self):
        return f"Parameter({self._name!r}, {self._type.name}, {self._value!r})"


def _is_empty(value) -> bool:
    try:
        return len(value) == 0
    except TypeError:
        return False


def _normalize(type_: Parameter.Type, value):
    T = Parameter.Type
    if value is None or type_ == T.NOT_SET:
        return None
    if type_ == T.BOOL:
        return bool(value)
    if type_ == T.INTEGER:
        return int(value)
    if type_ == T.DOUBLE:
        return float(value)
    if type_ == T.STRING:
        return str(value)
    items = value.tolist() if isinstance(value, np.ndarray) else value
    if type_ == T.BYTE_ARRAY:
        if isinstance(items, (bytes, bytearray)):
            return bytes(items)
        return b"".join(items) if items else b""
    convert = {T.BOOL_ARRAY: bool, T.INTEGER_ARRAY: int, T.DOUBLE_ARRAY: float, T.STRING_ARRAY: str}[type_]
    return [convert(v) for v in items]


def python_to_parameter_value(type_: Parameter.Type, value) -> ParameterValue:
    """A ParameterValue message holding ``value`` of type ``type_``."""
    T = Parameter.Type
    msg = ParameterValue(type=int(type_))
    if type_ == T.NOT_SET or value is None:
        msg.type = int(T.NOT_SET) if value is None else int(type_)
        return msg
    if type_ == T.BOOL:
        msg.bool_value = bool(value)
    elif type_ == T.INTEGER:
        msg.integer_value = int(value)
    elif type_ == T.DOUBLE:
        msg.double_value = float(value)
    elif type_ == T.STRING:
        msg.string_value = str(value)
    elif type_ == T.BYTE_ARRAY:
        msg.byte_array_value = np.frombuffer(bytes(value), dtype=np.uint8).copy()
    elif type_ == T.BOOL_ARRAY:
        msg.bool_array_value = np.asarray(value, dtype=bool).reshape(-1)
    elif type_ == T.INTEGER_ARRAY:
        msg.integer_array_value = np.asarray(value, dtype=np.int64).reshape(-1)
    elif type_ == T.DOUBLE_ARRAY:
        msg.double_array_value = np.asarray(value, dtype=np.float64).reshape(-1)
    elif type_ == T.STRING_ARRAY:
        msg.string_array_value = strings(value)
    return msg


def parameter_value_to_python(msg: ParameterValue):
    """The Python value a ParameterValue message holds (None for NOT_SET)."""
    T = Parameter.Type
    try:
        type_ = T(msg.type)
    except ValueError:
        raise InvalidParameterValueException("?", msg.type, "unknown ParameterValue.type code") from None
    if type_ == T.NOT_SET:
        return None
    return {
        T.BOOL: lambda: bool(msg.bool_value),
        T.INTEGER: lambda: int(msg.integer_value),
        T.DOUBLE: lambda: float(msg.double_value),
        T.STRING: lambda: str(msg.string_value),
        T.BYTE_ARRAY: lambda: bytes(np.asarray(msg.byte_array_value, dtype=np.uint8)),
        T.BOOL_ARRAY: lambda: [bool(v) for v in msg.bool_array_value],
        T.INTEGER_ARRAY: lambda: [int(v) for v in msg.integer_array_value],
        T.DOUBLE_ARRAY: lambda: [float(v) for v in msg.double_array_value],
        T.STRING_ARRAY: lambda: texts(msg.string_array_value),
    }[type_]()


def _copy_descriptor(descriptor: ParameterDescriptor | None) -> ParameterDescriptor:
    if descriptor is None:
        return ParameterDescriptor()
    if not isinstance(descriptor, ParameterDescriptor):
        raise InvalidParameterValueException("?", descriptor, "descriptor must be a ParameterDescriptor")
    return ParameterDescriptor(
        name=descriptor.name, type=descriptor.type, description=descriptor.description,
        additional_constraints=descriptor.additional_constraints, read_only=descriptor.read_only,
        dynamic_typing=descriptor.dynamic_typing,
        floating_point_range=[FloatingPointRange(from_value=r.from_value, to_value=r.to_value, step=r.step)
                              for r in descriptor.floating_point_range],
        integer_range=[IntegerRange(from_value=r.from_value, to_value=r.to_value, step=r.step)
                       for r in descriptor.integer_range])


def _range_problem(descriptor: ParameterDescriptor, parameter: Parameter) -> str | None:
    T = Parameter.Type
    value = parameter.value
    if parameter.type_ == T.DOUBLE and descriptor.floating_point_range:
        r = descriptor.floating_point_range[0]
        tolerance = 1e-9 * max(1.0, abs(r.from_value), abs(r.to_value))
        if not (r.from_value - tolerance <= value <= r.to_value + tolerance):
            return f"value {value} is outside the range [{r.from_value}, {r.to_value}]"
        if r.step > 0 and not math.isclose(value, r.to_value, abs_tol=tolerance):
            steps = (value - r.from_value) / r.step
            if abs(steps - round(steps)) * r.step > tolerance:
                return f"value {value} is not on a step of {r.step} from {r.from_value}"
    if parameter.type_ == T.INTEGER and descriptor.integer_range:
        bounds = descriptor.integer_range[0]
        if not (bounds.from_value <= value <= bounds.to_value):
            return f"value {value} is outside the range [{bounds.from_value}, {bounds.to_value}]"
        if bounds.step > 1 and value != bounds.to_value and (value - bounds.from_value) % bounds.step:
            return f"value {value} is not on a step of {bounds.step} from {bounds.from_value}"
    return None


def _type_problem(descriptor: ParameterDescriptor, parameter: Parameter) -> str | None:
    T = Parameter.Type
    declared = T(descriptor.type)
    if descriptor.dynamic_typing or declared == T.NOT_SET or parameter.type_ == declared:
        return None
    if parameter.type_ == T.NOT_SET:
        return f"parameter {parameter.name!r} is statically typed ({declared.name}) and cannot be unset"
    if declared.is_array and parameter.type_.is_array and _is_empty(parameter.value):
        return None
    hint = " (write the value with a decimal point, e.g. 1.0)" if (declared, parameter.type_) == (
        T.DOUBLE, T.INTEGER) else ""
    return (f"Wrong parameter type, parameter {parameter.name!r} is of type {declared.name}, setting it to "
            f"{parameter.type_.name} is not allowed{hint}")


class NodeParameters:
    """The parameters of one node (what ``Node.declare_parameter`` and friends delegate to).

    Parameters
    ----------
    overrides : dict
        ``{name: (value, origin)}`` from the command line, files and ``parameter_overrides``.
    allow_undeclared : bool
        Whether getting/setting undeclared names is allowed (rclpy's ``allow_undeclared_parameters``).
    """

    def __init__(self, overrides: dict, *, allow_undeclared: bool = False):
        self._overrides = dict(overrides)
        self._allow_undeclared = bool(allow_undeclared)
        self._values: dict[str, Parameter] = {}
        self._descriptors: dict[str, ParameterDescriptor] = {}
        self._callbacks: list = []
        self._post_set_callbacks: list = []
        self._lock = threading.RLock()

    @property
    def overrides(self) -> dict:
        """``{name: (value, origin)}`` (read-only copy)."""
        return dict(self._overrides)

    # -- declaration ------------------------------------------------------------------------------

    def declare(self, name, value=None, descriptor=None, ignore_override=False) -> Parameter:
        validate_parameter_name(name)
        descriptor = _copy_descriptor(descriptor)
        T = Parameter.Type
        with self._lock:
            if name in self._values:
                raise ParameterAlreadyDeclaredException(name)
            empty_default = False
            if isinstance(value, Parameter.Type):
                static_type, default = value, None
            else:
                default = Parameter(name, value=value)
                static_type, default = default.type_, default.value
                empty_default = static_type.is_array and _is_empty(default)
            explicit_type = descriptor.type != T.NOT_SET
            descriptor.name = name
            origin = "the declared default"
            final = Parameter(name, value=default)
            if not ignore_override and name in self._overrides:
                override, origin = self._overrides[name]
                try:
                    final = Parameter(name, value=override)
                except InvalidParameterValueException as exc:
                    raise InvalidParameterValueException(name, override, f"{exc} (from {origin})") from None
            if not explicit_type:
                # an empty list default fits any array type: the override (if an array) decides
                # and a parameter declared without a value takes the type of the first value it gets
                adopt = (empty_default and final.type_.is_array) or static_type == T.NOT_SET
                descriptor.type = int(final.type_ if adopt else static_type)
            if T(descriptor.type).is_array and final.type_.is_array and _is_empty(final.value):
                final = Parameter(name, T(descriptor.type), [])
            problem = _type_problem(descriptor, final) if final.type_ != T.NOT_SET else None
            if problem:
                raise InvalidParameterTypeException(name, f"{problem}; the value {final.value!r} comes from {origin}")
            problem = _range_problem(descriptor, final)
            if problem:
                raise InvalidParameterValueException(name, final.value, f"{problem} (from {origin})")
            if final.type_ != T.NOT_SET:
                result = self._ask_callbacks([final])
                if not result.successful:
                    raise InvalidParameterValueException(name, final.value, f"{result.reason} (from {origin})")
            if final.type_ == T.NOT_SET and static_type != T.NOT_SET:
                final = Parameter(name)  # statically typed, uninitialized
            self._values[name] = final
            self._descriptors[name] = descriptor
            return final

    def declare_many(self, namespace: str, parameters, ignore_override=False) -> list[Parameter]:
        """``parameters``: tuples ``(name,)``, ``(name, value)`` or ``(name, value, descriptor)``."""
        if not isinstance(namespace, str):
            raise InvalidParameterException(namespace, "namespace must be a str ('' for none)")
        declared = []
        for entry in parameters:
            if isinstance(entry, str) or not isinstance(entry, (tuple, list)) or not 1 <= len(entry) <= 3:
                raise InvalidParameterValueException(
                    "?", entry, "each entry must be a tuple (name,), (name, value) or (name, value, descriptor)")
            name = f"{namespace}.{entry[0]}" if namespace else entry[0]
            value = entry[1] if len(entry) > 1 else None
            descriptor = entry[2] if len(entry) > 2 else None
            declared.append(self.declare(name, value, descriptor, ignore_override))
        return declared

    def undeclare(self, name) -> None:
        with self._lock:
            if name not in self._values:
                raise ParameterNotDeclaredException(name)
            if self._descriptors[name].read_only:
                raise ParameterImmutableException(name)
            del self._values[name]
            del self._descriptors[name]

    # -- reading ----------------------------------------------------------------------------------

    def has(self, name) -> bool:
        with self._lock:
            return name in self._values

    def get(self, name) -> Parameter:
        with self._lock:
            if name in self._values:
                parameter = self._values[name]
                if parameter.type_ == Parameter.Type.NOT_SET and self._descriptors[name].type != 0 \
                        and not self._descriptors[name].dynamic_typing:
                    raise ParameterUninitializedException(name)
                return parameter
            if self._allow_undeclared:
                return Parameter(name)
            raise ParameterNotDeclaredException(name)

    def get_or(self, name, alternative_value=None) -> Parameter:
        with self._lock:
            if name in self._values:
                return self._values[name]
        if isinstance(alternative_value, Parameter):
            return alternative_value
        return Parameter(name, value=alternative_value)

    def by_prefix(self, prefix: str) -> dict[str, Parameter]:
        """``{name without "prefix.": Parameter}`` of the parameters under ``prefix``."""
        with self._lock:
            if not prefix:
                return dict(self._values)
            head = prefix + "."
            return {name[len(head):]: p for name, p in self._values.items() if name.startswith(head)}

    def names(self) -> list[str]:
        with self._lock:
            return sorted(self._values)

    def describe(self, name) -> ParameterDescriptor:
        with self._lock:
            if name in self._descriptors:
                return _copy_descriptor(self._descriptors[name])
            if self._allow_undeclared:
                return ParameterDescriptor(name=name)
            raise ParameterNotDeclaredException(name)

    def list(self, prefixes=None, depth: int = 0) -> ListParametersResult:
        """Names under any of ``prefixes`` (all when empty), at most ``depth`` levels below (0 = any)."""
        prefixes = list(prefixes or [])
        names = []
        with self._lock:
            for name in sorted(self._values):
                if prefixes:
                    for prefix in prefixes:
                        if name == prefix or name.startswith(prefix + "."):
                            rest = name[len(prefix) + 1:] if name != prefix else ""
                            if depth == 0 or rest.count(".") < depth:
                                names.append(name)
                            break
                elif depth == 0 or name.count(".") < depth:
                    names.append(name)
        found_prefixes = sorted({name.rsplit(".", 1)[0] for name in names if "." in name})
        return ListParametersResult(names=strings(names), prefixes=strings(found_prefixes))

    # -- writing ----------------------------------------------------------------------------------

    def add_on_set_parameters_callback(self, callback) -> None:
        if not callable(callback):
            raise ValueError(f"callback must be callable; got {callback!r}")
        with self._lock:
            self._callbacks.insert(0, callback)  # rclpy calls the most recently added first

    def remove_on_set_parameters_callback(self, callback) -> None:
        with self._lock:
            try:
                self._callbacks.remove(callback)
            except ValueError:
                raise ValueError("callback was not added with add_on_set_parameters_callback") from None

    def add_post_set_parameters_callback(self, callback) -> None:
        """``callback(parameters)`` after every successful set, with the parameters set (their new values)."""
        if not callable(callback):
            raise ValueError(f"callback must be callable; got {callback!r}")
        with self._lock:
            self._post_set_callbacks.append(callback)

    def remove_post_set_parameters_callback(self, callback) -> None:
        with self._lock:
            try:
                self._post_set_callbacks.remove(callback)
            except ValueError:
                raise ValueError("callback was not added with add_post_set_parameters_callback") from None

    def _ask_callbacks(self, parameters) -> SetParametersResult:
        for callback in list(self._callbacks):
            result = callback(list(parameters))
            if not isinstance(result, SetParametersResult):
                raise ValueError(f"on-set-parameters callback {callback!r} must return a SetParametersResult; "
                                 f"got {type(result).__name__}")
            if not result.successful:
                return result
        return SetParametersResult(successful=True)

    def _check_declared(self, parameters) -> None:
        for parameter in parameters:
            if not isinstance(parameter, Parameter):
                raise InvalidParameterValueException("?", parameter, "set_parameters takes a list of Parameter")
            if parameter.name not in self._values and not self._allow_undeclared:
                raise ParameterNotDeclaredException(parameter.name)

    def set(self, parameters) -> builtins.list[SetParametersResult]:  # builtins: the method list() shadows it
        """Set each parameter on its own; one result per parameter."""
        parameters = list(parameters)
        with self._lock:
            self._check_declared(parameters)
            return [self.set_atomically([p]) for p in parameters]

    def set_atomically(self, parameters) -> SetParametersResult:
        """Set all or none of ``parameters``."""
        parameters = list(parameters)
        T = Parameter.Type
        with self._lock:
            self._check_declared(parameters)
            for parameter in parameters:
                descriptor = self._descriptors.get(parameter.name)
                if descriptor is None:
                    continue  # undeclared, allowed: implicitly declared with dynamic typing below
                if descriptor.read_only:
                    return SetParametersResult(successful=False,
                                               reason=f"Trying to set a read-only parameter: {parameter.name}")
                problem = _type_problem(descriptor, parameter) or _range_problem(descriptor, parameter)
                if problem:
                    return SetParametersResult(successful=False, reason=problem)
            result = self._ask_callbacks(parameters)
            if not result.successful:
                return result
            for parameter in parameters:
                descriptor = self._descriptors.get(parameter.name)
                if parameter.type_ == T.NOT_SET:
                    self._values.pop(parameter.name, None)
                    self._descriptors.pop(parameter.name, None)
                    continue
                if descriptor is None:
                    self._descriptors[parameter.name] = ParameterDescriptor(
                        name=parameter.name, type=int(parameter.type_), dynamic_typing=True)
                elif descriptor.type == T.NOT_SET and not descriptor.dynamic_typing:
                    descriptor.type = int(parameter.type_)  # declared without a value: the first value types it
                value = parameter
                if descriptor is not None and T(descriptor.type).is_array and parameter.type_ != T(descriptor.type) \
                        and _is_empty(parameter.value) and not descriptor.dynamic_typing:
                    value = Parameter(parameter.name, T(descriptor.type), [])
                self._values[parameter.name] = value
            for callback in list(self._post_set_callbacks):
                callback(list(parameters))
            return SetParametersResult(successful=True)
