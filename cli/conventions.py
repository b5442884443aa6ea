"""The command line's one convention, shared by every sub-command.

- Sizes are ``WIDTHxHEIGHT`` in pixels (``640x480``), as ``--size`` always was: :func:`parse_size`.
- Lists are one comma-separated value (``--noise 1.5693,3.1386``): :func:`parse_list`.
- A rig file is ``--rig`` (dptpu-rig/1 or OpenCV file, ``CAM.mat,PRJ.mat`` or a preset).
- Point-cloud files are in metres; ``--units mm`` asks for millimetres: :data:`CLOUD_UNITS`.
- A command that runs more than a couple of seconds shows a tqdm bar on stderr and takes ``--quiet`` (none):
  :func:`add_quiet_option`; one made of a few stages shows them on one line: :func:`stage_bar`.

An old spelling is refused with one line that names the new one, and exit code 2 (never a silent change of
meaning: ``--crop 64x128`` meant height 64, so it is not reused for width first): :func:`add_renamed_option`.
"""
from __future__ import annotations

import argparse
import contextlib
import sys
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any, NoReturn, TypeVar

__all__ = ["CLOUD_UNITS", "LOG_BAR_DELAY_S", "add_cloud_units_option", "add_quiet_option", "add_renamed_option",
           "parse_list", "parse_size", "stage_bar"]

T = TypeVar("T")

#: The units a point-cloud file may be written in: metres (the default, ROS's unit) or millimetres.
CLOUD_UNITS = ("m", "mm")


def parse_size(text: str, option: str) -> tuple[int, int]:
    """``"640x480"`` -> ``(640, 480)``: width first, both positive integers.

    Raises
    ------
    ValueError
        One line naming ``option`` and the expected form.
    """
    parts = str(text).strip().lower().split("x")
    try:
        width, height = (int(part) for part in parts)
    except ValueError:
        raise ValueError(f"{option} must be WIDTHxHEIGHT in pixels, e.g. 640x480; got {text!r}") from None
    if width < 1 or height < 1:
        raise ValueError(f"{option} must be WIDTHxHEIGHT with both > 0, e.g. 640x480; got {text!r}")
    return width, height


def parse_list(text: str, option: str, kind: Callable[[str], T], *, example: str = "1.5693,3.1386") -> tuple[T, ...]:
    """``parse_list("1.5,3", "--noise", float)`` -> ``(1.5, 3.0)``: one comma-separated value, items converted by
    ``kind``.

    Raises
    ------
    ValueError
        An item ``kind`` refuses, or an empty list; one line naming ``option``.
    """
    items = [item.strip() for item in str(text).split(",")]
    if not any(items):
        raise ValueError(f"{option} must list at least one value, comma separated, e.g. {example}; got {text!r}")
    values = []
    for item in items:
        if not item:
            raise ValueError(f"{option} is a comma-separated list without empty items, e.g. {example}; "
                             f"got {text!r}")
        try:
            values.append(kind(item))
        except ValueError:
            raise ValueError(f"{option} is a comma-separated list, e.g. {example}; {item!r} is not valid "
                             f"(got {text!r})") from None
    return tuple(values)


class _RenamedOption(argparse.Action):
    """An old spelling: using it prints one line naming the new one and exits with code 2."""

    def __init__(self, option_strings, dest, *, replacement: str, **kwargs: Any):
        self.replacement = replacement
        super().__init__(option_strings, dest, nargs="?", help=argparse.SUPPRESS, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None) -> NoReturn:
        print(f"{parser.prog}: error: {option_string} is no longer accepted; {self.replacement}", file=sys.stderr)
        raise SystemExit(2)


def add_renamed_option(parser: argparse.ArgumentParser, old: str, replacement: str) -> None:
    """Refuse the old option ``old`` with ``replacement`` (what to write instead), hidden from ``--help``."""
    parser.add_argument(old, action=_RenamedOption, replacement=replacement, dest=f"_renamed_{old.lstrip('-')}")


def add_cloud_units_option(parser: argparse.ArgumentParser) -> None:
    """``--units m|mm``: the unit of the point-cloud file written (default metres)."""
    parser.add_argument("--units", choices=CLOUD_UNITS, default="m",
                        help="unit of the point-cloud file: m (default, as every cloud file of dptpu) or mm")


def add_quiet_option(parser: argparse.ArgumentParser, what: str = "no progress bar on stderr") -> None:
    """``--quiet``: the long-running command's progress (its tqdm bar, or its progress lines) is not shown; its
    summary on stdout and its errors are. ``what`` is the help text."""
    parser.add_argument("--quiet", action="store_true", help=what)


#: Seconds before a stage bar appears where stderr is not a terminal (a pipe, a log file, a test's capture).
LOG_BAR_DELAY_S = 2.0


@contextlib.contextmanager
def stage_bar(command: str, *, quiet: bool) -> Iterator[Callable[[str], None]]:
    """A one-line tqdm bar on stderr for a command made of a few stages: ``step(label)`` starts the next stage.

    On a terminal every stage is shown as it starts. Elsewhere (a pipe, a log file), as the other tqdm bars of dptpu,
    the bar is shown too, but only once the command has run for :data:`LOG_BAR_DELAY_S` (a timer draws it then, in
    the middle of a stage too): a command that ends sooner, or stops at once on bad input, writes only its summary
    or its one-line error.

    Parameters
    ----------
    command : str
        The line's prefix, e.g. ``"sim render"``.
    quiet : bool
        ``--quiet``: no bar at all.

    Examples
    --------
    >>> with stage_bar("sim render", quiet=args.quiet) as step:
    ...     step("reading the rig")
    ...     step("rendering 24 frames")
    """
    from tqdm import tqdm  # only while such a command runs: keeps `dptpu --help` fast

    terminal = bool(getattr(sys.stderr, "isatty", lambda: False)())
    delay_s = 0.0 if terminal else LOG_BAR_DELAY_S
    with tqdm(unit="step", file=sys.stderr, disable=quiet, delay=delay_s,
              bar_format=command + ": step {n_fmt} [{elapsed}] {desc}") as bar:
        shown_from = time.time() + delay_s  # (tqdm.start_t: not set on a disabled bar)
        timer = None
        if not quiet and delay_s > 0:  # tqdm draws a delayed bar only on an update: one when the delay is over
            timer = threading.Timer(delay_s, bar.update, args=(0,))
            timer.daemon = True
            timer.start()

        def step(label: str) -> None:
            bar.set_description_str(label, refresh=False)
            bar.update(1)
            # every stage shown as it starts, however soon after the last (update skips a draw within 0.1 s)
            if not quiet and bar.last_print_n != bar.n and time.time() >= shown_from:
                bar.refresh()

        try:
            yield step
        finally:
            if timer is not None:
                timer.cancel()
