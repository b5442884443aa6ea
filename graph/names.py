"""ROS 2 names: validation, expansion of relative and ``~`` private names, and remapping rules.

Rules (as ROS 2, ``design.ros2.org/articles/topic_and_service_names.html``):

- A node name is one token: letters, digits and ``_``, not starting with a digit, e.g. ``talker``.
- A namespace is absolute (``/`` or ``/a/b``); one given without the leading ``/`` gets it, as rcl does.
- A topic or service name is absolute (``/camera/image_raw``), relative (``image_raw``: prefixed with
  the node's namespace) or private (``~/status``: prefixed with the node's fully qualified name).
  ``{node}`` and ``{ns}`` (or ``{namespace}``) are replaced by the node's name and namespace. Tokens
  are letters, digits and ``_`` and must not start with a digit; no ``//``, no trailing ``/``.
- A remapping rule ``from:=to`` (optionally ``node_name:from:=to`` to apply to one node only) matches a
  name after both were expanded in the node's namespace; the first matching rule wins. ``__node:=``
  (alias ``__name:=``) renames the node, ``__ns:=`` moves it to another namespace.

Convention: the root namespace is ``"/"``; a node ``talker`` in it has the fully qualified name
``/talker``; in ``/scanner`` it is ``/scanner/talker``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from .exceptions import (
    InvalidNamespaceException,
    InvalidNodeNameException,
    InvalidServiceNameException,
    InvalidTopicNameException,
    ROSArgumentsError,
)

__all__ = [
    "MAX_NAME_LENGTH",
    "validate_node_name",
    "validate_namespace",
    "normalize_namespace",
    "validate_full_topic_name",
    "expand_topic_name",
    "fully_qualified_name",
    "logger_name_of",
    "RemapRule",
    "parse_remap_rule",
    "remap_node_name",
    "remap_namespace",
    "remap_name",
]

#: Longest accepted name, characters (ROS 2's limit for topic names).
MAX_NAME_LENGTH = 255

_TOKEN = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
_SUBSTITUTION = re.compile(r"\{([^{}]*)\}")


def validate_node_name(name) -> str:
    """Return ``name`` if it is a valid node name, else raise :class:`InvalidNodeNameException`."""
    if not isinstance(name, str):
        raise InvalidNodeNameException(name, f"must be a str; got {type(name).__name__}")
    if not name:
        raise InvalidNodeNameException(name, "must not be empty")
    if len(name) > MAX_NAME_LENGTH:
        raise InvalidNodeNameException(name, f"longer than {MAX_NAME_LENGTH} characters")
    if not _TOKEN.match(name):
        raise InvalidNodeNameException(
            name, "must hold only letters, digits and '_' and must not start with a digit (e.g. 'phase_node')")
    return name


def _check_tokens(tokens, name, error, what: str) -> None:
    for token in tokens:
        if token == "":
            raise error(name, f"{what} must not contain '//' or end with '/'")
        if not _TOKEN.match(token):
            raise error(name, f"token {token!r} must hold only letters, digits and '_' and must not start "
                              "with a digit")


def normalize_namespace(namespace) -> str:
    """``None`` or ``""`` -> ``"/"``; ``"a/b"`` -> ``"/a/b"``; then validate (see :func:`validate_namespace`)."""
    if namespace is None or namespace == "":
        return "/"
    if isinstance(namespace, str) and not namespace.startswith("/"):
        namespace = "/" + namespace
    return validate_namespace(namespace)


def validate_namespace(namespace) -> str:
    """Return ``namespace`` if it is a valid absolute namespace, else raise :class:`InvalidNamespaceException`."""
    if not isinstance(namespace, str):
        raise InvalidNamespaceException(namespace, f"must be a str; got {type(namespace).__name__}")
    if not namespace.startswith("/"):
        raise InvalidNamespaceException(namespace, "must be absolute (start with '/')")
    if len(namespace) > MAX_NAME_LENGTH:
        raise InvalidNamespaceException(namespace, f"longer than {MAX_NAME_LENGTH} characters")
    if namespace != "/":
        _check_tokens(namespace[1:].split("/"), namespace, InvalidNamespaceException, "a namespace")
    return namespace


def validate_full_topic_name(name, *, is_service: bool = False) -> str:
    """Return ``name`` if it is a valid fully qualified topic (or service) name, else raise."""
    error = InvalidServiceNameException if is_service else InvalidTopicNameException
    if not isinstance(name, str):
        raise error(name, f"must be a str; got {type(name).__name__}")
    if not name.startswith("/") or name == "/":
        raise error(name, "a fully qualified name must start with '/' and have at least one token")
    if len(name) > MAX_NAME_LENGTH:
        raise error(name, f"longer than {MAX_NAME_LENGTH} characters")
    _check_tokens(name[1:].split("/"), name, error, "a name")
    return name


def fully_qualified_name(namespace: str, name: str) -> str:
    """``("/", "talker")`` -> ``"/talker"``; ``("/a", "talker")`` -> ``"/a/talker"``."""
    return f"/{name}" if namespace == "/" else f"{namespace}/{name}"


def logger_name_of(namespace: str, node_name: str) -> str:
    """The logger name rclpy gives a node: namespace tokens and name joined by dots (``/a/b`` -> ``a.b``)."""
    return fully_qualified_name(namespace, node_name)[1:].replace("/", ".")


def expand_topic_name(name, node_name: str, namespace: str, *, is_service: bool = False) -> str:
    """Expand a relative, private or absolute name into a validated fully qualified name.

    Parameters
    ----------
    name : str
        ``"/abs/name"``, ``"relative/name"``, ``"~"``, ``"~/private"``; may use ``{node}``, ``{ns}``.
    node_name, namespace : str
        The node's (already validated) name and absolute namespace.
    is_service : bool
        Only changes the error class (:class:`InvalidServiceNameException`).

    Examples
    --------
    >>> expand_topic_name("image", "cam", "/rig")
    '/rig/image'
    >>> expand_topic_name("~/status", "cam", "/rig")
    '/rig/cam/status'
    """
    error = InvalidServiceNameException if is_service else InvalidTopicNameException
    if not isinstance(name, str):
        raise error(name, f"must be a str; got {type(name).__name__}")
    if not name:
        raise error(name, "must not be empty")
    original = name
    if "~" in name[1:] or (name.startswith("~") and len(name) > 1 and name[1] != "/"):
        raise error(original, "'~' may only appear alone or as the first character followed by '/'")
    node_fqn = fully_qualified_name(namespace, node_name)

    def substitute(match: re.Match) -> str:
        key = match.group(1)
        if key == "node":
            return node_name
        if key in ("ns", "namespace"):
            return namespace.rstrip("/") if namespace != "/" else ""
        raise error(original, f"unknown substitution {{{key}}}; known: {{node}}, {{ns}}, {{namespace}}")

    if "{" in name or "}" in name:
        name = _SUBSTITUTION.sub(substitute, name)
        if "{" in name or "}" in name:
            raise error(original, "unbalanced '{' or '}'")
    if name.startswith("~"):
        name = node_fqn + name[1:]
    elif not name.startswith("/"):
        name = fully_qualified_name(namespace, name)
    if name.endswith("/") and name != "/":
        raise error(original, "must not end with '/'")
    try:
        return validate_full_topic_name(name, is_service=is_service)
    except (InvalidTopicNameException, InvalidServiceNameException) as exc:
        if name == original:
            raise
        raise error(original, f"expands to {name!r}, which is invalid: {exc.reason}") from None


# --------------------------------------------------------------------------------------------------
# Remapping
# --------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class RemapRule:
    """One remapping rule from ``-r [node:]from:=to``.

    Attributes
    ----------
    match, replacement : str
        Names as written (expanded per node when applied), or ``__node``/``__ns`` rules.
    node : str or None
        Only nodes with this (original) name use the rule; None = every node.
    kind : {"name", "node", "namespace"}
        ``node`` for ``__node:=``/``__name:=``, ``namespace`` for ``__ns:=``, else ``name``.
    scope : {"any", "topic", "service"}
        ``rostopic://from:=to`` applies to topics only, ``rosservice://`` to services only.
    """

    match: str
    replacement: str
    node: str | None = None
    kind: str = "name"
    scope: str = "any"


def parse_remap_rule(text) -> RemapRule:
    """Parse ``"from:=to"``, ``"node:from:=to"``, ``"__node:=name"``, ``"__ns:=/ns"``.

    Raises
    ------
    ROSArgumentsError
        If the rule lacks ``:=`` or either side is empty or invalid.
    """
    if not isinstance(text, str) or ":=" not in text:
        raise ROSArgumentsError(f"remapping rule must look like 'from:=to'; got {text!r}")
    left, _, right = text.partition(":=")
    if not right:
        raise ROSArgumentsError(f"remapping rule {text!r} has an empty replacement (after ':=')")
    node = None
    scope = "any"
    for prefix, kind in (("rostopic://", "topic"), ("rosservice://", "service")):
        if left.startswith(prefix):
            left, scope = left[len(prefix):], kind
    # "node:from" -- the node prefix is a single token before the first ':'
    head, sep, tail = left.partition(":")
    if sep:
        node, left = head, tail
        for prefix, kind in (("rostopic://", "topic"), ("rosservice://", "service")):
            if left.startswith(prefix):
                left, scope = left[len(prefix):], kind
        try:
            validate_node_name(node)
        except InvalidNodeNameException as exc:
            raise ROSArgumentsError(f"remapping rule {text!r}: node prefix: {exc}") from None
    if not left:
        raise ROSArgumentsError(f"remapping rule {text!r} has an empty name to match (before ':=')")
    if left in ("__node", "__name"):
        try:
            validate_node_name(right)
        except InvalidNodeNameException as exc:
            raise ROSArgumentsError(f"remapping rule {text!r}: {exc}") from None
        return RemapRule(left, right, node, "node")
    if left == "__ns":
        try:
            normalize_namespace(right)
        except InvalidNamespaceException as exc:
            raise ROSArgumentsError(f"remapping rule {text!r}: {exc}") from None
        return RemapRule(left, right, node, "namespace")
    if left.startswith("__"):
        raise ROSArgumentsError(f"remapping rule {text!r}: unknown special name {left!r}; known: __node, "
                                "__name, __ns")
    # check both sides are names (expansion with a dummy node catches syntax errors early)
    for side in (left, right):
        try:
            expand_topic_name(side, "node", "/")
        except InvalidTopicNameException as exc:
            raise ROSArgumentsError(f"remapping rule {text!r}: {exc}") from None
    return RemapRule(left, right, node, "name", scope)


def _applies(rule: RemapRule, node_name: str) -> bool:
    return rule.node is None or rule.node == node_name


def remap_node_name(rules, node_name: str) -> str:
    """The node name after the first applicable ``__node:=`` rule (rules in order)."""
    for rule in rules:
        if rule.kind == "node" and _applies(rule, node_name):
            return rule.replacement
    return node_name


def remap_namespace(rules, node_name: str, namespace: str) -> str:
    """The namespace after the first applicable ``__ns:=`` rule (``node_name`` is the original name)."""
    for rule in rules:
        if rule.kind == "namespace" and _applies(rule, node_name):
            return normalize_namespace(rule.replacement)
    return namespace


def remap_name(rules, expanded_name: str, node_name: str, namespace: str, *, original_node_name: str | None = None,
               is_service: bool = False) -> str:
    """Apply the first matching name rule to a fully qualified name.

    Parameters
    ----------
    rules : sequence of RemapRule
        In command-line order; node-specific rules (``talker:a:=b``) are matched against
        ``original_node_name`` (the name in code, before ``__node:=``), defaulting to ``node_name``.
    expanded_name : str
        The name after :func:`expand_topic_name`.
    node_name, namespace : str
        The node's final name and namespace; both sides of a rule are expanded with them.
    """
    match_node = original_node_name or node_name
    for rule in rules:
        if rule.kind != "name" or not (_applies(rule, match_node) or _applies(rule, node_name)):
            continue
        if rule.scope != "any" and (rule.scope == "service") != is_service:
            continue
        if expand_topic_name(rule.match, node_name, namespace, is_service=is_service) == expanded_name:
            return expand_topic_name(rule.replacement, node_name, namespace, is_service=is_service)
    return expanded_name
