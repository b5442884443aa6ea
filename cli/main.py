"""The ``dptpu`` command line: a thin shell over the packages' functions.

Each sub-command lives in its own module of this package and exposes ``register(subparsers)``, which
adds its parser and sets ``func`` (a callable taking the parsed ``argparse.Namespace`` and returning an
exit code). Bad input raises ``ValueError`` (or an ``OSError`` such as ``FileNotFoundError``) inside the packages;
here it becomes one line on stderr (:func:`error_line`) and exit code 2, never a traceback.
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
        args = parser.parse_args(argv)
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
