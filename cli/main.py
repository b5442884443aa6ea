"""The ``dptpu`` command line: a thin shell over the packages' functions.

Each sub-command lives in its own module of this package and exposes ``register(subparsers)``, which
adds its parser and sets ``func`` (a callable taking the parsed ``argparse.Namespace`` and returning an
exit code). Bad input raises ``ValueError`` (or an ``OSError`` such as ``FileNotFoundError``) inside the packages;
here it becomes one line on stderr (:func:`error_line`) and exit code 2, never a traceback. A command line argparse
refuses is answered with the usage of the (sub-)command it was meant for (:func:`parse_command_line`), as for a
missing or invalid option: ``dptpu sim render --bogus`` prints ``usage: dptpu sim render ...``, not ``dptpu``'s.
"""
from __future__ import annotations

import argparse
import importlib
import sys

#: Modules of ``dptpu.cli`` that add sub-commands, in the order ``dptpu --help`` lists them.
COMMAND_MODULES = ("eval_cmd", "unwrap_cmd", "triangulate_cmd", "rig_cmd", "bench_cmd", "launch_cmd", "record_cmd",
                   "introspect_cmd", "sim_cmd", "calibrate_cmd", "train_cmd", "twin_cmd")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="dptpu", description="dptpu: structured-light 3D scanner tools")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_MODULES:
        try:
            module = importlib.import_module(f"dptpu.cli.{name}")
        except ModuleNotFoundError as exc:
            if exc.name != f"dptpu.cli.{name}":
                raise
            continue  # a command module not written yet
        module.register(subparsers)
    return parser


#: Exit code after Ctrl-C that a command did not handle itself (the shell's 128 + SIGINT).
INTERRUPTED_EXIT_CODE = 130


def main(argv: list[str] | None = None) -> int:
    """Run ``dptpu ARGS``; the exit code: 2 for bad input (one line on stderr), 130 after an unhandled Ctrl-C
    (nothing printed: while the commands' modules import, or in a command that does not stop on its own)."""
    try:
        parser = build_parser()
        args = parse_command_line(parser, sys.argv[1:] if argv is None else list(argv))
        if not getattr(args, "func", None):
            parser.print_help(sys.stderr)
            return 2
        try:
            return int(args.func(args) or 0)
        except (ValueError, OSError) as exc:  # OSError: FileNotFoundError, PermissionError, IsADirectoryError, ...
            print(f"dptpu {args.command}: error: {error_line(exc)}", file=sys.stderr)
            return 2
    except KeyboardInterrupt:
        return INTERRUPTED_EXIT_CODE


def parse_command_line(parser: argparse.ArgumentParser, argv: list[str]) -> argparse.Namespace:
    """``parser.parse_args(argv)``, except that arguments no parser takes are refused by the sub-command they were
    given to: its usage and ``dptpu SUB: error: unrecognized arguments: ...`` (exit code 2). argparse leaves them
    to the top-level parser, whose usage (``dptpu [-h] COMMAND ...``) says nothing about the command's options."""
    args, extras = parser.parse_known_args(argv)
    if extras:
        command_parser(parser, argv).error(f"unrecognized arguments: {' '.join(extras)}")
    return args


def command_parser(parser: argparse.ArgumentParser, argv: list[str]) -> argparse.ArgumentParser:
    """The parser of the deepest sub-command that ``argv`` names (``parser`` itself when it names none): each word
    that is a sub-command of the parser reached so far leads into it."""
    for word in argv:
        subcommands = next((action for action in parser._actions
                            if isinstance(action, argparse._SubParsersAction)), None)
        if subcommands is None:
            break
        if word in subcommands.choices:
            parser = subcommands.choices[word]
    return parser


def error_line(exc: BaseException) -> str:
    """One line for a bad input: the message on one line (a YAML parser's marks included); an ``OSError`` as
    ``FILE: reason``; an empty message as the error's type (never "")."""
    if isinstance(exc, OSError) and exc.filename is not None and exc.strerror:
        text = f"{exc.filename}: {exc.strerror}"
    else:
        text = str(exc)
    return " ".join(text.split()) or type(exc).__name__


if __name__ == "__main__":
    sys.exit(main())
