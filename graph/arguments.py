"""The ROS 2 command line: ``--ros-args`` flags for remapping, parameters and log levels.

Everything between ``--ros-args`` and ``--`` (or the end) is for the runtime; everything else belongs
to the program (:func:`remove_ros_args` gives it back). Supported flags, as ``ros2 run``:

==============================  =====================================================================
``-r/--remap FROM:=TO``         remap a topic or service name; ``node:FROM:=TO`` for one node only;
                                ``__node:=NAME`` (``__name``) and ``__ns:=/NS`` rename and move the node
``-p/--param NAME:=VALUE``      set a parameter; VALUE is YAML (``3``, ``2.5``, ``true``, ``[1, 2]``, text)
``--params-file FILE``          a ROS 2 parameters YAML file (``node: {ros__parameters: {...}}``)
``--log-level LEVEL``           default log level; ``--log-level NAME:=LEVEL`` for one logger
``--enable-/--disable-*-logs``  accepted and ignored (rosout, stdout, external lib)
==============================  =====================================================================

An unknown flag raises :class:`UnknownROSArgsError`, like rcl. Parameter sources keep their order:
when two set the same parameter, the later one wins.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field
from pathlib import Path

from .exceptions import ROSArgumentsError, UnknownROSArgsError
from .logging import parse_severity
from .names import RemapRule, parse_remap_rule
from .param_files import ParameterSource, parse_param_assignment, read_params_file

__all__ = ["RosArguments", "parse_ros_arguments", "remove_ros_args", "ROS_ARGS_FLAG"]

ROS_ARGS_FLAG = "--ros-args"
_END_FLAG = "--"
_IGNORED_FLAGS = {"--enable-rosout-logs", "--disable-rosout-logs", "--enable-stdout-logs", "--disable-stdout-logs",
                  "--enable-external-lib-logs", "--disable-external-lib-logs"}


@dataclass
class RosArguments:
    """The parsed ROS part of a command line.

    Attributes
    ----------
    remap_rules : list of RemapRule
        In command-line order (the first matching rule wins).
    parameter_sources : list of ParameterSource
        ``--params-file`` files and ``-p`` assignments in command-line order (later wins).
    log_levels : dict
        ``{"": default severity, "logger.name": severity}``.
    non_ros_args : list of str
        The arguments outside ``--ros-args ... --``.
    """

    remap_rules: list[RemapRule] = field(default_factory=list)
    parameter_sources: list[ParameterSource] = field(default_factory=list)
    log_levels: dict = field(default_factory=dict)
    non_ros_args: list[str] = field(default_factory=list)


def _value_after(args, index: int, flag: str) -> str:
    if index + 1 >= len(args) or args[index + 1] in (ROS_ARGS_FLAG, _END_FLAG):
        raise ROSArgumentsError(f"{flag} needs a value after it (e.g. {flag} {_EXAMPLES[flag]})")
    return args[index + 1]


_EXAMPLES = {"-r": "chatter:=talk", "--remap": "chatter:=talk", "-p": "rate_hz:=10.0", "--param": "rate_hz:=10.0",
             "--params-file": "params.yaml", "--log-level": "debug", "-e": "/enclave", "--enclave": "/enclave",
             "--log-config-file": "file.config"}


def parse_ros_arguments(args) -> RosArguments:
    """Parse a command line (``sys.argv``-like list of str; may be None = nothing).

    Raises
    ------
    UnknownROSArgsError
        A flag after ``--ros-args`` that is not supported.
    ROSArgumentsError
        A malformed rule, assignment or level, or a params file that cannot be read or parsed.
    """
    result = RosArguments()
    if args is None:
        return result
    if isinstance(args, (str, bytes)) or not all(isinstance(a, str) for a in args):
        raise ROSArgumentsError(f"args must be a list of str (like sys.argv); got {args!r}")
    args = list(args)
    in_ros = False
    index = 0
    while index < len(args):
        arg = args[index]
        if arg == ROS_ARGS_FLAG:
            in_ros = True
        elif not in_ros:
            result.non_ros_args.append(arg)
        elif arg == _END_FLAG:
            in_ros = False
        elif arg in ("-r", "--remap"):
            result.remap_rules.append(parse_remap_rule(_value_after(args, index, arg)))
            index += 1
        elif arg in ("-p", "--param"):
            result.parameter_sources.append(parse_param_assignment(_value_after(args, index, arg)))
            index += 1
        elif arg == "--params-file":
            result.parameter_sources.append(read_params_file(Path(_value_after(args, index, arg))))
            index += 1
        elif arg == "--log-level":
            _parse_log_level(_value_after(args, index, arg), result.log_levels)
            index += 1
        elif arg in ("-e", "--enclave", "--log-config-file"):
            _value_after(args, index, arg)  # accepted, no effect here
            index += 1
        elif arg in _IGNORED_FLAGS:
            pass
        else:
            raise UnknownROSArgsError(f"unknown ROS argument {arg!r} after --ros-args; supported: -r/--remap, "
                                      "-p/--param, --params-file, --log-level (end the ROS part with '--')")
        index += 1
    return result


def _parse_log_level(text: str, levels: dict) -> None:
    name, sep, level = text.rpartition(":=")
    if not sep:
        name, level = "", text
    try:
        levels[name] = parse_severity(level)
    except ValueError as exc:
        raise ROSArgumentsError(f"--log-level {text}: {exc}") from None


def remove_ros_args(args=None) -> list[str]:
    """``args`` without the ROS part (rclpy.utilities.remove_ros_args); ``None`` means ``sys.argv``."""
    if args is None:
        args = sys.argv
    out, in_ros = [], False
    for arg in args:
        if arg == ROS_ARGS_FLAG:
            in_ros = True
        elif in_ros and arg == _END_FLAG:
            in_ros = False
        elif not in_ros:
            out.append(arg)
    return out
