"""An EMULATOR of the projector's trigger box: speaks ``dptpu-trigger/1`` on a pseudo-terminal.

The real trigger box (a microcontroller in front of a DLP LightCrafter 4500, docs/projector-protocol.md)
cannot exist on a build machine; this module stands in for it. It is an emulator, not a driver: no
light is projected. It behaves like the box on the wire: it answers ``HELLO``, ``LOAD``, ``START`` and
``STOP``, and during a scan sends one ``ACK`` per pattern, spaced by the loaded exposure, then ``DONE``.
Faults can be switched on to test the node: abort after some patterns (``ABORT ... DLP_FAULT``), fall
silent mid-scan, never answer at all, or put garbage lines on the wire.

Three ways to use it:

- :class:`TriggerBoxEmulator`, the state machine alone: ``receive(line, now)``, then ``due(now)`` gives
  the lines to send. The projector node uses it on a ``loop://`` port (see ``dptpu.nodes.projector``).
- :class:`PtyTriggerBox`: the state machine served on a pseudo-terminal (``os.openpty``) by a thread;
  ``box.port`` is the path to open with pyserial (a symlink when ``link=`` is given).
- ``python -m dptpu.nodes.projector.emulator --link /tmp/ttyBOX [--abort-after N] [--hang-after N]
  [--garbage-every K] [--silent]``: the same as its own process. It prints JSON lines on stdout
  (``{"event": "ready", "port": ...}``, one ``{"event": "command", ...}`` per host line) and runs
  until SIGINT or SIGTERM. Killing it makes the port disappear; starting it again with the same
  ``--link`` brings the port back at the same path, as udev's ``/dev/serial/by-id`` links do.
"""

from __future__ import annotations

import argparse
import bisect
import json
import os
import select
import signal
import sys
import threading
import time
import tty
from collections import deque
from pathlib import Path

from .protocol import (
    ProtocolError,
    Reply,
    SequenceSpec,
    encode_reply,
    parse_command,
)

__all__ = ["PtyTriggerBox", "TriggerBoxEmulator", "main", "serve_fd"]

FIRMWARE = "emulator-1.0"
#: Commands :attr:`TriggerBoxEmulator.commands` keeps (the last ones).
COMMANDS_KEPT = 100
#: Lines the emulator puts on the wire with ``garbage_every``: noise, a wrong baud rate, a truncated line.
GARBAGE_LINES = (b"\xff\xfe\x00garbage\x81\n", b"ACK x y\n", b"%%&*(\n", b"ACK 4294967296 1\n", b"HELLO\n")


class TriggerBoxEmulator:
    """The trigger box's behaviour as a state machine (no I/O, no threads).

    Parameters
    ----------
    firmware : str
        Sent in the ``HELLO`` reply.
    abort_after : int, optional
        During every scan, send ``ABORT <scan> <n> DLP_FAULT`` after ``n`` patterns instead of finishing.
    hang_after : int, optional
        During every scan, fall silent after ``n`` patterns (no ``DONE``, no ``ABORT``).
    silent : bool
        Never answer anything (a box that is powered off, or a port with nothing on it).
    garbage_every : int
        When > 0, send one garbage line (:data:`GARBAGE_LINES`, in turn) before every ``garbage_every``-th line.
    start_delay_s : float
        Time from ``START`` to the first pattern on screen, seconds.
    """

    def __init__(self, *, firmware: str = FIRMWARE, abort_after: int | None = None, hang_after: int | None = None,
                 silent: bool = False, garbage_every: int = 0, start_delay_s: float = 0.002):
        self.firmware = firmware
        self.abort_after = abort_after
        self.hang_after = hang_after
        self.silent = silent
        self.garbage_every = garbage_every
        self.start_delay_s = start_delay_s
        self.sequence: SequenceSpec | None = None
        # the last parsed commands, oldest first: bounded, since a loop:// projector node runs for days (a list of
        # every command grew the node by 3 % over 6000 scans, issue 19)
        self.commands: deque = deque(maxlen=COMMANDS_KEPT)
        self._queue: list[tuple[float, bytes]] = []  # (due time, line), sorted by time
        self._scan_until = 0.0            # monotonic time the running scan ends (0: idle)
        self._sent = 0

    @property
    def scanning(self) -> bool:
        """True while the patterns of a scan are being shown."""
        return bool(self._queue) and self._scan_until > 0

    def receive(self, line: bytes, now: float) -> None:
        """Handle one host line received at monotonic time ``now`` (seconds)."""
        try:
            command = parse_command(line)
        except ProtocolError as exc:
            code = "BADCMD" if "unknown command" in str(exc) or "empty" in str(exc) else "BADARG"
            self._reply(now, Reply("ERR", code=code, text=_safe_text(str(exc))))
            return
        self.commands.append(command)
        busy = self._scan_until > now and self._queue
        if command.kind == "HELLO":
            self._reply(now, Reply("HELLO", firmware=self.firmware))
        elif command.kind == "STOP":
            self._queue.clear()
            self._scan_until = 0.0
            self._reply(now, Reply("STOPPED"))
        elif busy:
            self._reply(now, Reply("ERR", code="BUSY", text="a scan is running; send STOP first"))
        elif command.kind == "LOAD":
            if command.sequence is None:  # parse_command gives every LOAD its sequence; a hand-made one may lack it
                self._reply(now, Reply("ERR", code="BADARG", text="LOAD needs a sequence"))
                return
            self.sequence = command.sequence
            self._reply(now, Reply("LOADED", count=command.sequence.pattern_count))
        elif command.kind == "START":
            if self.sequence is None:
                self._reply(now, Reply("ERR", code="NOSEQ", text="no sequence loaded; send LOAD first"))
                return
            self._start(self.sequence, command.scan_id, now)

    def _start(self, sequence: SequenceSpec, scan_id: int, now: float) -> None:
        count = sequence.pattern_count
        period_s = sequence.exposure_us * 1e-6
        self._reply(now, Reply("STARTED", scan_id=scan_id))
        shown = count
        for limit in (self.abort_after, self.hang_after):
            if limit is not None:
                shown = min(shown, limit)
        first = now + self.start_delay_s
        for index in range(shown):
            self._reply(first + index * period_s, Reply("ACK", scan_id=scan_id, index=index))
        end = first + shown * period_s
        if self.abort_after is not None and self.abort_after < count and shown == self.abort_after:
            self._reply(end, Reply("ABORT", scan_id=scan_id, count=shown, code="DLP_FAULT",
                                   text=f"pattern {shown} not confirmed by the DLP"))
        elif shown == count:
            self._reply(end, Reply("DONE", scan_id=scan_id, count=count))
        self._scan_until = end

    def _reply(self, when: float, reply: Reply) -> None:
        if self.silent:
            return
        bisect.insort(self._queue, (when, encode_reply(reply)), key=_due_time)  # after equal times: in order

    def next_due(self) -> float | None:
        """Monotonic time of the next line to send, or None."""
        return self._queue[0][0] if self._queue else None

    def due(self, now: float) -> list[bytes]:
        """The lines due by ``now``, in order (garbage interleaved when ``garbage_every`` > 0)."""
        lines = []
        while self._queue and self._queue[0][0] <= now:
            _, line = self._queue.pop(0)
            self._sent += 1
            if self.garbage_every and self._sent % self.garbage_every == 0:
                lines.append(GARBAGE_LINES[(self._sent // self.garbage_every) % len(GARBAGE_LINES)])
            lines.append(line)
        if not self._queue:
            self._scan_until = 0.0
        return lines


def _due_time(item: tuple[float, bytes]) -> float:
    return item[0]


def _safe_text(text: str) -> str:
    cleaned = "".join(ch if ch.isprintable() and ch.isascii() else "?" for ch in text)
    return " ".join(cleaned.split())[:80]


def serve_fd(fd: int, emulator: TriggerBoxEmulator, stop: threading.Event, on_command=None) -> None:
    """Serve ``emulator`` on file descriptor ``fd`` (a pty master) until ``stop`` is set.

    Reads host lines, hands them to the emulator, writes its replies when they are due. ``on_command``
    (optional) is called with each raw host line.
    """
    buffer = b""
    while not stop.is_set():
        now = time.monotonic()
        for line in emulator.due(now):
            try:
                os.write(fd, line)
            except OSError:
                pass  # nobody has the port open: the bytes go nowhere, as on a real wire
        next_due = emulator.next_due()
        wait_s = 0.05 if next_due is None else min(0.05, max(0.0, next_due - time.monotonic()))
        try:
            readable, _, _ = select.select([fd], [], [], wait_s)
        except (OSError, ValueError):
            return
        if not readable:
            continue
        try:
            chunk = os.read(fd, 4096)
        except OSError:
            time.sleep(0.02)  # EIO: the host side is closed; it may open again
            continue
        buffer += chunk
        while b"\n" in buffer:
            line, buffer = buffer.split(b"\n", 1)
            if on_command is not None:
                on_command(line)
            emulator.receive(line, time.monotonic())
        if len(buffer) > 4096:
            buffer = b""


class PtyTriggerBox:
    """A :class:`TriggerBoxEmulator` served on a fresh pseudo-terminal by a background thread.

    Parameters
    ----------
    link : path, optional
        Also make this symlink point at the pty (replaced if it exists; removed by :meth:`close`).
    **options
        Passed to :class:`TriggerBoxEmulator`.

    Attributes
    ----------
    port : str
        What to open with pyserial: ``link`` if given, else the pty's ``/dev/pts/N``.
    """

    def __init__(self, *, link=None, on_command=None, **options):
        self.emulator = TriggerBoxEmulator(**options)
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)  # keep our own end open: the port stays, whoever opens or closes it
        self.device = os.ttyname(self._slave)
        self.link = Path(link) if link is not None else None
        if self.link is not None:
            temporary = self.link.with_name(self.link.name + ".new")
            temporary.unlink(missing_ok=True)
            temporary.symlink_to(self.device)
            os.replace(temporary, self.link)
        self.port = str(self.link) if self.link is not None else self.device
        self._stop = threading.Event()
        self._thread = threading.Thread(target=serve_fd, args=(self._master, self.emulator, self._stop, on_command),
                                        name="trigger-box-emulator", daemon=True)
        self._thread.start()

    def close(self) -> None:
        """Unplug: stop serving, close the pty (the host sees the port fail) and remove the link."""
        self._stop.set()
        self._thread.join(timeout=2.0)
        for fd in (self._master, self._slave):
            try:
                os.close(fd)
            except OSError:
                pass
        if self.link is not None and self.link.is_symlink() and os.readlink(self.link) == self.device:
            self.link.unlink(missing_ok=True)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def main(argv: list[str] | None = None) -> int:
    """Run the emulator as its own process (see the module docstring); returns the exit code."""
    parser = argparse.ArgumentParser(prog="python -m dptpu.nodes.projector.emulator",
                                     description="EMULATOR of the dptpu-trigger/1 trigger box on a pseudo-terminal")
    parser.add_argument("--link", help="symlink to create for the pty (a stable port path)")
    parser.add_argument("--abort-after", type=int, help="send ABORT ... DLP_FAULT after this many patterns")
    parser.add_argument("--hang-after", type=int, help="fall silent after this many patterns of a scan")
    parser.add_argument("--silent", action="store_true", help="never answer")
    parser.add_argument("--garbage-every", type=int, default=0, help="a garbage line before every K-th line")
    parser.add_argument("--firmware", default=FIRMWARE)
    args = parser.parse_args(argv)

    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    signal.signal(signal.SIGINT, lambda *_: stop.set())

    printing = threading.Lock()  # the box's thread reports commands while the main thread reports "ready"

    def emit(event: dict) -> None:
        """One JSON event a line on stdout; whole lines only, whichever thread reports."""
        with printing:
            sys.stdout.write(json.dumps(event) + "\n")
            sys.stdout.flush()

    def report(line: bytes) -> None:
        emit({"event": "command", "line": line.decode("ascii", "replace").rstrip("\r")})

    box = PtyTriggerBox(link=args.link, on_command=report, firmware=args.firmware, abort_after=args.abort_after,
                        hang_after=args.hang_after, silent=args.silent, garbage_every=args.garbage_every)
    emit({"event": "ready", "port": box.port, "device": box.device})
    try:
        while not stop.wait(0.1):
            pass
    finally:
        box.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
