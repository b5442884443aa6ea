"""The trigger box's line protocol, ``dptpu-trigger/1``: encode commands, parse replies (pure functions).

The trigger box is a microcontroller between the host's serial port and a DLP LightCrafter 4500: it
loads a pattern sequence into the projector, starts it, and reports each pattern the moment the DLP's
trigger output says it is on screen. The full description, with a transcript, is
``docs/projector-protocol.md``. In short (``->`` host to box, ``<-`` box to host; ASCII lines ending in
``\\n``, tokens separated by one space, at most :data:`MAX_LINE_BYTES` bytes)::

    -> HELLO                                      <- HELLO dptpu-trigger/1 <firmware>
    -> LOAD <axis> <width> <height> <exposure_us> <f>x<N>[,<f>x<N>...][,white][,black]
                                                  <- LOADED <pattern_count>
    -> START <scan_id>                            <- STARTED <scan_id>
                                                  <- ACK <scan_id> <index>        one per displayed pattern
                                                  <- DONE <scan_id> <count>       all patterns shown
                                                  <- ABORT <scan_id> <displayed> <REASON> [text]
    -> STOP                                       <- STOPPED
    any refused command                           <- ERR <CODE> <text>

Nothing here does I/O: :func:`encode_command` and :func:`parse_reply` are used by the projector node,
:func:`parse_command` and :func:`encode_reply` by the emulator (``dptpu.nodes.projector.emulator``).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from functools import cached_property

__all__ = ["PROTOCOL", "MAX_LINE_BYTES", "ERROR_CODES", "REFERENCES", "ProtocolError", "SequenceSpec",
           "split_references", "parse_sequence_spec",
           "format_sequence_spec", "Command", "Reply", "encode_command", "parse_command", "encode_reply",
           "parse_reply"]

PROTOCOL = "dptpu-trigger/1"
MAX_LINE_BYTES = 120
#: ``ERR`` codes: unknown command, bad argument, START before LOAD, command refused during a scan.
ERROR_CODES = ("BADCMD", "BADARG", "NOSEQ", "BUSY")
COMMANDS = ("HELLO", "LOAD", "START", "STOP")
REPLIES = ("HELLO", "LOADED", "STARTED", "ACK", "DONE", "ABORT", "STOPPED", "ERR")
MAX_SCAN_ID = 2**32 - 1
#: Reference frames a sequence may end with (one pattern each).
REFERENCES = ("white", "black")
_TOKEN = re.compile(r"^[A-Za-z0-9_.:/+-]+$")


class ProtocolError(ValueError):
    """A line that is not valid ``dptpu-trigger/1``; the message quotes the line and says what was expected."""


@dataclass(frozen=True)
class SequenceSpec:
    """What ``LOAD`` sends: the projector's patterns, in projection order.

    Attributes
    ----------
    fringe_axis : str
        ``"x"`` (vertical stripes; extent = width) or ``"y"``.
    projector_size : tuple of int
        ``(width, height)`` of the projector, pixels.
    exposure_us : int
        Display time of one pattern, microseconds (the LightCrafter's pattern exposure).
    entries : tuple of (float, int)
        ``(frequency, steps)`` per pattern set: fringe periods across the extent, and ``N >= 3``.
    references : tuple of str
        Reference frames shown after the fringe sets, each one pattern: ``"white"`` (the projector full on) and
        ``"black"`` (full off), each at most once (the texture of the scan, ``dptpu.fpp.texture``).
    """

    fringe_axis: str
    projector_size: tuple[int, int]
    exposure_us: int
    entries: tuple = field(default_factory=tuple)
    references: tuple = field(default_factory=tuple)

    def __post_init__(self):
        if self.fringe_axis not in ("x", "y"):
            raise ValueError(f"fringe_axis must be 'x' or 'y'; got {self.fringe_axis!r}")
        size = tuple(self.projector_size)
        if len(size) != 2 or not all(isinstance(v, int) and not isinstance(v, bool) and 0 < v < 65536
                                     for v in size):
            raise ValueError(f"projector_size must be (width, height), integers in [1, 65535]; got "
                             f"{self.projector_size!r}")
        if isinstance(self.exposure_us, bool) or not isinstance(self.exposure_us, int) \
                or not 100 <= self.exposure_us <= 10_000_000:
            raise ValueError(f"exposure_us must be an integer in [100, 10000000] microseconds; got "
                             f"{self.exposure_us!r}")
        if not self.entries:
            raise ValueError("a pattern sequence needs at least one entry (frequency x steps)")
        for frequency, steps in self.entries:
            if not (math.isfinite(frequency) and frequency > 0):
                raise ValueError(f"frequency must be finite and > 0 (periods across the extent); got {frequency!r}")
            if isinstance(steps, bool) or not isinstance(steps, int) or not 3 <= steps <= 256:
                raise ValueError(f"steps must be an integer in [3, 256]; got {steps!r}")
        references = tuple(self.references)
        if any(kind not in REFERENCES for kind in references) or len(set(references)) != len(references):
            raise ValueError(f"references must be 'white' and/or 'black', each at most once; got {references!r}")
        object.__setattr__(self, "projector_size", size)
        object.__setattr__(self, "entries", tuple((float(f), int(n)) for f, n in self.entries))
        object.__setattr__(self, "references", references)

    @cached_property  # asked three times a displayed pattern (the link thread's Trigger); the spec is frozen
    def pattern_count(self) -> int:
        """Total number of patterns, ``sum(N)`` and one per reference frame."""
        return sum(steps for _, steps in self.entries) + len(self.references)

    def locate(self, pattern_index: int) -> tuple[float, int, int]:
        """``(frequency, steps, step)`` of pattern ``pattern_index`` (0-based, projection order); ``(0.0, 1, 0)``
        for a reference frame (:meth:`kind_of` tells which)."""
        if not 0 <= pattern_index < self.pattern_count:
            raise ValueError(f"pattern_index must be in [0, {self.pattern_count}); got {pattern_index}")
        remaining = pattern_index
        for frequency, steps in self.entries:
            if remaining < steps:
                return frequency, steps, remaining
            remaining -= steps
        return 0.0, 1, 0

    def kind_of(self, pattern_index: int) -> str:
        """``"phase"``, or ``"white"`` / ``"black"`` for a reference frame."""
        fringes = self.pattern_count - len(self.references)
        return self.references[pattern_index - fringes] if pattern_index >= fringes else "phase"


def split_references(text: str) -> tuple[str, tuple[str, ...]]:
    """``"96x12,1x12,white,black"`` -> ``("96x12,1x12", ("white", "black"))``: the fringe sets and the reference
    frames that end the sequence (ValueError for a reference before a fringe set, naming it)."""
    if not isinstance(text, str):
        raise ValueError(f"sequence must be a string like '96x12,1x12,white'; got {text!r}")
    items = [item.strip() for item in text.split(",")]
    references: list[str] = []
    while items and items[-1].lower() in REFERENCES:
        references.insert(0, items.pop().lower())
    misplaced = [item for item in items if item.lower() in REFERENCES]
    if misplaced:
        raise ValueError(f"sequence entry {misplaced[0]!r}: reference frames (white, black) come after the fringe "
                         f"sets, e.g. 96x12,1x12,white,black; in {text!r}")
    return ",".join(items), tuple(references)


def parse_sequence_spec(text: str) -> tuple[tuple[float, int], ...]:
    """``"96x12,1x12"`` -> ``((96.0, 12), (1.0, 12))``: ``frequency x steps`` entries in projection order.

    The frequency is the number of fringe periods across the projector extent and may be rational
    (``"10.9x3"``). Raises ValueError naming the bad entry and the expected form. Reference frames (``white``,
    ``black``) are split off first by :func:`split_references`.
    """
    if not isinstance(text, str) or not text.strip():
        raise ValueError(f"sequence must look like '96x12,1x12' (frequency x steps, comma separated); got {text!r}")
    entries = []
    for item in text.split(","):
        match = re.fullmatch(r"\s*([0-9]+(?:\.[0-9]+)?)\s*[xX]\s*([0-9]+)\s*", item)
        if match is None:
            raise ValueError(f"sequence entry {item.strip()!r} must be <frequency>x<steps>, e.g. 96x12; "
                             f"in {text!r}")
        frequency, steps = float(match.group(1)), int(match.group(2))
        if frequency <= 0 or steps < 3:
            raise ValueError(f"sequence entry {item.strip()!r} needs frequency > 0 and steps >= 3; in {text!r}")
        entries.append((frequency, steps))
    return tuple(entries)


def format_sequence_spec(entries, references=()) -> str:
    """Inverse of :func:`parse_sequence_spec` (and :func:`split_references`): ``((96.0, 12), (10.9, 3))``,
    ``("white",)`` -> ``"96x12,10.9x3,white"``."""
    return ",".join([f"{_number(frequency)}x{int(steps)}" for frequency, steps in entries] + list(references))


def _number(value: float) -> str:
    text = f"{float(value):.10g}"
    if "e" in text or "inf" in text or "nan" in text:
        raise ValueError(f"frequency {value!r} cannot be written as a plain decimal number")
    return text


@dataclass(frozen=True)
class Command:
    """A host command. ``kind`` is one of ``HELLO``, ``LOAD`` (``sequence``), ``START`` (``scan_id``), ``STOP``."""

    kind: str
    sequence: SequenceSpec | None = None
    scan_id: int = 0


@dataclass(frozen=True)
class Reply:
    """A box line. Fields used by each ``kind``:

    ``HELLO``: ``protocol``, ``firmware``; ``LOADED``: ``count``; ``STARTED``: ``scan_id``;
    ``ACK``: ``scan_id``, ``index``; ``DONE``: ``scan_id``, ``count``; ``ABORT``: ``scan_id``,
    ``count`` (patterns displayed), ``code`` (reason token), ``text``; ``STOPPED``: none;
    ``ERR``: ``code``, ``text``.
    """

    kind: str
    scan_id: int = 0
    index: int = 0
    count: int = 0
    code: str = ""
    text: str = ""
    protocol: str = ""
    firmware: str = ""


def encode_command(command: Command) -> bytes:
    """The line (with ``\\n``) that sends ``command``."""
    if command.kind in ("HELLO", "STOP"):
        line = command.kind
    elif command.kind == "START":
        line = f"START {_check_scan_id(command.scan_id)}"
    elif command.kind == "LOAD":
        spec = command.sequence
        if spec is None:
            raise ValueError("a LOAD command needs a sequence")
        width, height = spec.projector_size
        line = (f"LOAD {spec.fringe_axis} {width} {height} {spec.exposure_us} "
                f"{format_sequence_spec(spec.entries, spec.references)}")
    else:
        raise ValueError(f"unknown command kind {command.kind!r}; expected one of {', '.join(COMMANDS)}")
    return _finish(line)


def encode_reply(reply: Reply) -> bytes:
    """The line (with ``\\n``) the box sends for ``reply``."""
    kind = reply.kind
    if kind == "HELLO":
        line = f"HELLO {_token(reply.protocol or PROTOCOL)} {_token(reply.firmware or 'unknown')}"
    elif kind == "LOADED":
        line = f"LOADED {int(reply.count)}"
    elif kind == "STARTED":
        line = f"STARTED {_check_scan_id(reply.scan_id)}"
    elif kind == "ACK":
        line = f"ACK {_check_scan_id(reply.scan_id)} {int(reply.index)}"
    elif kind == "DONE":
        line = f"DONE {_check_scan_id(reply.scan_id)} {int(reply.count)}"
    elif kind == "ABORT":
        line = f"ABORT {_check_scan_id(reply.scan_id)} {int(reply.count)} {_token(reply.code)}"
        line += f" {reply.text}" if reply.text else ""
    elif kind == "STOPPED":
        line = "STOPPED"
    elif kind == "ERR":
        if reply.code not in ERROR_CODES:
            raise ValueError(f"ERR code must be one of {', '.join(ERROR_CODES)}; got {reply.code!r}")
        line = f"ERR {reply.code}" + (f" {reply.text}" if reply.text else "")
    else:
        raise ValueError(f"unknown reply kind {kind!r}; expected one of {', '.join(REPLIES)}")
    return _finish(line)


def parse_command(line) -> Command:
    """The :class:`Command` of one host line (bytes or str, with or without its line ending)."""
    text = _text(line)
    tokens = text.split(" ")
    kind = tokens[0]
    if kind in ("HELLO", "STOP"):
        _arity(text, tokens, 1)
        return Command(kind)
    if kind == "START":
        _arity(text, tokens, 2)
        return Command(kind, scan_id=_uint(text, tokens[1], "scan_id", MAX_SCAN_ID))
    if kind == "LOAD":
        _arity(text, tokens, 6)
        try:
            fringes, references = split_references(tokens[5])
            sequence = SequenceSpec(tokens[1], (_uint(text, tokens[2], "width", 65535),
                                                _uint(text, tokens[3], "height", 65535)),
                                    _uint(text, tokens[4], "exposure_us", 10_000_000),
                                    parse_sequence_spec(fringes), references)
        except ProtocolError:
            raise
        except ValueError as exc:
            raise ProtocolError(f"bad LOAD line {text!r}: {exc}") from None
        return Command(kind, sequence=sequence)
    raise ProtocolError(f"unknown command in {text!r}; expected one of {', '.join(COMMANDS)}")


def parse_reply(line) -> Reply:
    """The :class:`Reply` of one box line; :class:`ProtocolError` for anything else (garbage, echo, noise)."""
    text = _text(line)
    tokens = text.split(" ")
    kind = tokens[0]
    if kind == "HELLO":
        if len(tokens) == 1:
            raise ProtocolError(f"{text!r} is a command, not a reply (an echo: is this a loopback port?)")
        _arity(text, tokens, 3)
        if tokens[1] != PROTOCOL:
            raise ProtocolError(f"the box speaks {tokens[1]!r}, this node speaks {PROTOCOL!r} (line {text!r})")
        return Reply(kind, protocol=tokens[1], firmware=tokens[2])
    if kind == "LOADED":
        _arity(text, tokens, 2)
        return Reply(kind, count=_uint(text, tokens[1], "pattern_count", 65535))
    if kind == "STARTED":
        _arity(text, tokens, 2)
        return Reply(kind, scan_id=_uint(text, tokens[1], "scan_id", MAX_SCAN_ID))
    if kind == "ACK":
        _arity(text, tokens, 3)
        return Reply(kind, scan_id=_uint(text, tokens[1], "scan_id", MAX_SCAN_ID),
                     index=_uint(text, tokens[2], "index", 65535))
    if kind == "DONE":
        _arity(text, tokens, 3)
        return Reply(kind, scan_id=_uint(text, tokens[1], "scan_id", MAX_SCAN_ID),
                     count=_uint(text, tokens[2], "count", 65535))
    if kind == "ABORT":
        if len(tokens) < 4:
            raise ProtocolError(f"{text!r}: ABORT needs <scan_id> <displayed> <REASON> [text]")
        return Reply(kind, scan_id=_uint(text, tokens[1], "scan_id", MAX_SCAN_ID),
                     count=_uint(text, tokens[2], "displayed", 65535), code=tokens[3], text=" ".join(tokens[4:]))
    if kind == "STOPPED":
        _arity(text, tokens, 1)
        return Reply(kind)
    if kind == "ERR":
        if len(tokens) < 2 or tokens[1] not in ERROR_CODES:
            raise ProtocolError(f"{text!r}: ERR needs a code among {', '.join(ERROR_CODES)}")
        return Reply(kind, code=tokens[1], text=" ".join(tokens[2:]))
    if kind in COMMANDS:
        raise ProtocolError(f"{text!r} is a command, not a reply (an echo: is this a loopback port?)")
    raise ProtocolError(f"not a {PROTOCOL} reply: {text!r}")


# --- helpers ---------------------------------------------------------------------------------------------

def _text(line) -> str:
    if isinstance(line, (bytes, bytearray, memoryview)):
        raw = bytes(line)
        if len(raw) > MAX_LINE_BYTES + 2:
            raise ProtocolError(f"line of {len(raw)} bytes is longer than {MAX_LINE_BYTES}: {raw[:40]!r}...")
        try:
            line = raw.decode("ascii")
        except UnicodeDecodeError:
            raise ProtocolError(f"line is not ASCII (wrong baud rate or noise?): {raw[:40]!r}") from None
    text = line.rstrip("\r\n")
    if not text:
        raise ProtocolError("empty line")
    if len(text) > MAX_LINE_BYTES:
        raise ProtocolError(f"line of {len(text)} characters is longer than {MAX_LINE_BYTES}: {text[:40]!r}...")
    if not text.isprintable() or "  " in text or text != text.strip():
        raise ProtocolError(f"line has control characters or stray spaces: {text[:40]!r}")
    return text


def _arity(text: str, tokens: list[str], count: int) -> None:
    if len(tokens) != count:
        raise ProtocolError(f"{text!r}: {tokens[0]} takes {count - 1} argument(s); got {len(tokens) - 1}")


def _uint(text: str, token: str, name: str, maximum: int) -> int:
    if not token.isdigit() or len(token) > 10 or int(token) > maximum:
        raise ProtocolError(f"{text!r}: {name} must be an integer in [0, {maximum}]; got {token!r}")
    return int(token)


def _token(value: str) -> str:
    if not _TOKEN.match(value or ""):
        raise ValueError(f"{value!r} is not a protocol token (letters, digits, _ . : / + -)")
    return value


def _check_scan_id(scan_id: int) -> int:
    if isinstance(scan_id, bool) or not isinstance(scan_id, int) or not 0 <= scan_id <= MAX_SCAN_ID:
        raise ValueError(f"scan_id must be an integer in [0, {MAX_SCAN_ID}]; got {scan_id!r}")
    return scan_id


def _finish(line: str) -> bytes:
    data = (line + "\n").encode("ascii")
    if len(data) > MAX_LINE_BYTES + 1:
        raise ValueError(f"line {line[:40]!r}... is longer than {MAX_LINE_BYTES} bytes")
    return data
