"""Which of a node's parameters apply at run time and how each is checked: :class:`ParameterRules`.

A node declares each parameter through its rules, either **settable** (a check that refuses a bad value with a
reason, and an apply that puts a set value to work, e.g. the next cloud's ``frame_id``) or **read-only** (the
descriptor's ``read_only``: the value is fixed at start-up, by the launch file or ``-p``, and ``param set`` is
refused with "Trying to set a read-only parameter"). This is rclpy's pattern (an on-set callback returning
``SetParametersResult(successful, reason)``, a post-set callback applying the values, ``ParameterDescriptor
(read_only=True)``) in one place per node.

The check runs at declaration too (on the launch file's or the command line's value): a bad start-up value is a
``ValueError`` naming the parameter, the value and where it came from (``dptpu.nodes.node_main`` prints it and the
node exits with code 2), and the same rule refuses the same value later, at run time.

```python
rules = ParameterRules(self)
self.frame_id = rules.settable("frame_id", "scanner_optical_frame", check=frame_id)
self.min_confidence = rules.settable("min_confidence", 0.2, check=within(0.0, 1.0))
rig_path = rules.read_only("rig", "", description="a dptpu-rig/1 file; restart the node to change it")
```

``dptpu param set /cloud frame_id base_link`` then changes ``self.frame_id`` between two callbacks (the node's
executor runs the parameter service), so the next cloud carries it; ``param set /cloud min_confidence 2.0`` answers
``Setting parameter failed: min_confidence must be within [0, 1]; got 2.0`` and the old value stays.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

from .rcl_interfaces import ParameterDescriptor, SetParametersResult

__all__ = ["Check", "ParameterRules", "at_least", "frame_id", "greater_than", "one_of", "within"]

#: A check: the value -> None when it is acceptable, else a predicate saying why not ("must be > 0; got -1", read
#: after the parameter's name); it may also raise ValueError, OSError or ImportError, whose message is the reason.
Check = Callable[[Any], "str | None"]
#: What a check may raise for a value it refuses.
_REFUSALS = (ValueError, OSError, ImportError)


class _Rule:
    __slots__ = ("check", "apply")

    def __init__(self, check: Check | None, apply: Callable[[Any], None]):
        self.check = check
        self.apply = apply


class ParameterRules:
    """The settable and read-only parameters of ``node``; registers its on-set and post-set callbacks.

    Parameters
    ----------
    node : dptpu.graph.node.Node
        The node whose parameters these are; create the rules before declaring any parameter through them.
    """

    def __init__(self, node) -> None:
        self._node = node
        self._rules: dict[str, _Rule] = {}
        self._pending: list = []  # the parameters being checked (one set call), for value()
        node.add_on_set_parameters_callback(self._check)
        node.add_post_set_parameters_callback(self._apply)

    # -- declaring ------------------------------------------------------------------------------------------

    def settable(self, name: str, default, *, check: Check | None = None,
                 apply: Callable[[Any], None] | None = None, description: str = ""):
        """Declare ``name`` as applying at run time; its start-up value.

        Parameters
        ----------
        name, default
            As ``Node.declare_parameter`` (the default's type is the parameter's).
        check : callable, optional
            ``check(value)``: None to accept, a predicate to refuse (e.g. "must be > 0; got -1": the refusal reads
            ``NAME must be > 0; got -1``); or it raises ValueError, OSError or ImportError, whose message (a
            whole sentence) is the refusal. It runs on the start-up value and on every
            ``param set``. A check that depends on other parameters reads them with :meth:`value`.
        apply : callable, optional
            ``apply(value)`` once a new value is set (default: ``setattr(node, name, value)``).
        description : str
            The descriptor's description (``dptpu param describe``).
        """
        self._rules[name] = _Rule(check, apply if apply is not None else self._setter(name))
        return self._node.declare_parameter(name, default, ParameterDescriptor(description=description)).value

    def read_only(self, name: str, default, *, description: str = "", dynamic_typing: bool = False):
        """Declare ``name`` read-only (fixed at start-up; ``param set`` is refused); its start-up value."""
        descriptor = ParameterDescriptor(description=description, read_only=True, dynamic_typing=dynamic_typing)
        return self._node.declare_parameter(name, default, descriptor).value

    def value(self, name: str):
        """The value of ``name`` as it will be if the set being checked is accepted: a check of one parameter that
        depends on another reads it here (``param set`` of both at once, atomically, sees both new values)."""
        for parameter in self._pending:
            if parameter.name == name:
                return parameter.value
        return self._node.get_parameter(name).value

    # -- callbacks ------------------------------------------------------------------------------------------

    def _setter(self, name: str) -> Callable[[Any], None]:
        def assign(value) -> None:
            setattr(self._node, name, value)
        return assign

    def _check(self, parameters) -> SetParametersResult:
        self._pending = list(parameters)
        try:
            return self._check_each(self._pending)
        finally:
            self._pending = []

    def _check_each(self, parameters) -> SetParametersResult:
        for parameter in parameters:
            rule = self._rules.get(parameter.name)
            if rule is None or rule.check is None:
                continue
            try:
                reason = rule.check(parameter.value)
                reason = f"{parameter.name} {reason}" if reason else None
            except _REFUSALS as exc:
                reason = str(exc) or f"{parameter.name}: {type(exc).__name__}"
            if reason:
                return SetParametersResult(successful=False, reason=reason)
        return SetParametersResult(successful=True)

    def _apply(self, parameters) -> None:
        for parameter in parameters:
            rule = self._rules.get(parameter.name)
            if rule is not None:
                rule.apply(parameter.value)
                self._node.get_logger().info(f"parameter {parameter.name} set to {parameter.value!r}")


# -- checks ---------------------------------------------------------------------------------------------------

def within(low: float, high: float) -> Check:
    """A check: ``low <= value <= high``."""
    def check(value):
        return None if low <= value <= high else f"must be within [{low:g}, {high:g}]; got {value}"
    return check


def at_least(low: float) -> Check:
    """A check: ``value >= low``."""
    def check(value):
        return None if value >= low else f"must be >= {low:g}; got {value}"
    return check


def greater_than(low: float) -> Check:
    """A check: ``value > low``."""
    def check(value):
        return None if value > low else f"must be > {low:g}; got {value}"
    return check


def one_of(choices: Sequence[str]) -> Check:
    """A check: ``value in choices``."""
    def check(value):
        return None if value in choices else f"must be one of {', '.join(choices)}; got {value!r}"
    return check


def frame_id(value: str) -> str | None:
    """A check of a TF frame id: non-empty, no spaces, no leading ``/`` (tf2 refuses one)."""
    if not value:
        return "must not be empty (a TF frame id)"
    if value.startswith("/"):
        return f"must not start with '/' (tf2 refuses such a frame id); got {value!r}"
    if any(c.isspace() for c in value):
        return f"must not contain spaces (a TF frame id); got {value!r}"
    return None
