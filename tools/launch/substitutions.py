"""``$(...)`` substitutions of launch files, with ROS 2's names and meaning.

=====================  ==============================================================================
``$(var NAME)``        the value of launch argument (or ``let``) ``NAME``; an undeclared name is an error
``$(env NAME)``        environment variable ``NAME``; an error when it is not set
``$(env NAME DEFAULT)`` environment variable ``NAME``, or ``DEFAULT`` when it is not set
``$(optenv NAME [DEFAULT])`` environment variable ``NAME``, or ``DEFAULT`` (default: empty) when not set
``$(dirname)``         the absolute directory of the launch file being read
``$(find-pkg-share dptpu)`` the folder holding the installed ``launch/`` folder (ROS 2: a package's share)
=====================  ==============================================================================

Arguments are separated by white space; quote one that holds spaces (``$(env GREETING 'hello world')``).
Substitutions nest (``$(env $(var which_env))``). Text around them is kept: ``"$(var ns)/camera"``.
There is no escape for a literal ``$(``.
"""
from __future__ import annotations

import difflib
import os
from collections.abc import Mapping
from dataclasses import dataclass, field

from .installed import PACKAGE_NAME, installed_launch_dir

__all__ = ["SubstitutionError", "SubstitutionContext", "substitute", "has_substitution", "SUBSTITUTIONS"]

#: The substitution names this module understands.
SUBSTITUTIONS = ("var", "env", "optenv", "dirname", "find-pkg-share")


class SubstitutionError(ValueError):
    """A ``$(...)`` is malformed, unknown, or names an undeclared argument / unset variable."""


@dataclass(frozen=True)
class SubstitutionContext:
    """What substitutions can see.

    variables : launch argument (and ``let``) values by name, all strings.
    launch_file_dir : absolute directory of the launch file being read, for ``$(dirname)``.
    environ : the environment for ``$(env)`` / ``$(optenv)`` (default: ``os.environ``).
    """

    variables: Mapping[str, str]
    launch_file_dir: str
    environ: Mapping[str, str] = field(default_factory=lambda: os.environ)


@dataclass(frozen=True)
class _Call:
    name: str
    args: tuple[tuple, ...]  # each argument is a tuple of parts (str or _Call)


def has_substitution(text: str) -> bool:
    """True when ``text`` contains a ``$(`` (whether or not it is well formed)."""
    return "$(" in text


def substitute(text: str, context: SubstitutionContext) -> str:
    """Return ``text`` with every ``$(...)`` replaced by its value.

    Raises
    ------
    SubstitutionError
        Unterminated ``$(``, an unknown substitution, wrong argument count, an undeclared ``$(var)``
        or an unset ``$(env NAME)`` without a default. The message says which and what is allowed.
    """
    if not has_substitution(text):
        return text
    parts, end = _parse_parts(text, 0, inside_call=False)
    assert end == len(text)
    return _evaluate(parts, context)


# ------------------------------------------------------------------------------------------------
# parsing: text -> parts (plain strings and calls)
# ------------------------------------------------------------------------------------------------

def _parse_parts(text: str, start: int, *, inside_call: bool, quote: str | None = None) -> tuple[tuple, int]:
    """Parts from ``start`` up to the end of the text, or (inside a call) up to the end of one argument."""
    parts: list = []
    literal: list[str] = []
    i = start
    while i < len(text):
        char = text[i]
        if text.startswith("$(", i):
            if literal:
                parts.append("".join(literal))
                literal = []
            call, i = _parse_call(text, i)
            parts.append(call)
            continue
        if quote is not None:
            if char == quote:
                break
        elif inside_call and (char.isspace() or char == ")"):
            break
        literal.append(char)
        i += 1
    else:
        if quote is not None:
            raise SubstitutionError(f"unterminated quote {quote} in {text!r}")
    if literal:
        parts.append("".join(literal))
    return tuple(parts), i


def _parse_call(text: str, start: int) -> tuple[_Call, int]:
    """A call starting at ``text[start:] == '$(...'``; returns it and the index after its ``)``."""
    i = start + 2
    name_start = i
    while i < len(text) and (text[i].isalnum() or text[i] in "-_"):
        i += 1
    name = text[name_start:i]
    if not name:
        raise SubstitutionError(f"a substitution needs a name after '$(' in {text!r}, "
                                f"one of: {', '.join(SUBSTITUTIONS)}")
    args: list[tuple] = []  # each a tuple of parts (str or _Call)
    while True:
        while i < len(text) and text[i].isspace():
            i += 1
        if i >= len(text):
            raise SubstitutionError(f"unterminated substitution '$({name}' in {text!r}: missing ')'")
        if text[i] == ")":
            return _Call(name, tuple(args)), i + 1
        if text[i] in "'\"":
            argument, i = _parse_parts(text, i + 1, inside_call=True, quote=text[i])
            i += 1  # the closing quote
            args.append(argument or ("",))
        else:
            argument, i = _parse_parts(text, i, inside_call=True)
            args.append(argument)


# ------------------------------------------------------------------------------------------------
# evaluation
# ------------------------------------------------------------------------------------------------

def _evaluate(parts: tuple, context: SubstitutionContext) -> str:
    return "".join(part if isinstance(part, str) else _call(part, context) for part in parts)


def _call(call: _Call, context: SubstitutionContext) -> str:
    args = [_evaluate(argument, context) for argument in call.args]
    if call.name == "var":
        _arity(call, args, 1, 1, "$(var NAME)")
        return _variable(args[0], context)
    if call.name == "env":
        _arity(call, args, 1, 2, "$(env NAME [DEFAULT])")
        value = context.environ.get(args[0])
        if value is None:
            if len(args) == 2:
                return args[1]
            raise SubstitutionError(f"environment variable {args[0]!r} is not set and $(env {args[0]}) has no "
                                    f"default; set it or write $(env {args[0]} DEFAULT)")
        return value
    if call.name == "optenv":
        _arity(call, args, 1, 2, "$(optenv NAME [DEFAULT])")
        return context.environ.get(args[0], args[1] if len(args) == 2 else "")
    if call.name == "dirname":
        _arity(call, args, 0, 0, "$(dirname)")
        return context.launch_file_dir
    if call.name == "find-pkg-share":
        _arity(call, args, 1, 1, f"$(find-pkg-share {PACKAGE_NAME})")
        if args[0] != PACKAGE_NAME:
            raise SubstitutionError(f"$(find-pkg-share {args[0]}): only this package's share is known here; "
                                    f"use $(find-pkg-share {PACKAGE_NAME})")
        return os.fspath(installed_launch_dir().parent)
    hint = difflib.get_close_matches(call.name, SUBSTITUTIONS, n=1)
    suggestion = f" (did you mean '{hint[0]}'?)" if hint else ""
    raise SubstitutionError(f"unknown substitution '$({call.name} ...)'{suggestion}; "
                            f"known: {', '.join(SUBSTITUTIONS)}")


def _arity(call: _Call, args: list[str], low: int, high: int, usage: str) -> None:
    if not low <= len(args) <= high:
        raise SubstitutionError(f"$({call.name}) takes {low if low == high else f'{low} to {high}'} "
                                f"argument{'s' if high != 1 else ''}, got {len(args)}; usage: {usage}")


def _variable(name: str, context: SubstitutionContext) -> str:
    if name in context.variables:
        return context.variables[name]
    declared = sorted(context.variables)
    hint = difflib.get_close_matches(name, declared, n=1)
    suggestion = f" (did you mean '{hint[0]}'?)" if hint else ""
    listing = ", ".join(declared) if declared else "none"
    raise SubstitutionError(f"undeclared launch argument {name!r} in $(var {name}){suggestion}; "
                            f"declare it with '- arg: {{name: {name}}}' (declared: {listing})")
