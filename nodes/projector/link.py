"""The projector node's serial link to the trigger box: one thread that owns the port.

It opens the port (pyserial: a device path, a pty path or a URL such as ``loop://``), says ``HELLO``,
``LOAD``\\ s the pattern sequence, then waits for scan requests and runs each one: ``START``, one callback
per ``ACK``, and one callback at the end with the number of patterns displayed and, when the scan did not
finish, why. Anything wrong with the port (missing, unplugged, silent, garbage only, the wrong
protocol) is logged in one line that says what to check; the port is closed and opened again after an
exponential backoff (``initial_s``, doubling, at most ``max_s``). The thread never ends on an error.

On ``loop://`` there is no box: pyserial echoes every byte written. The link then runs the trigger-box
EMULATOR (``dptpu.nodes.projector.emulator``) on the echoed commands and writes its answers into the loop,
so they come back through pyserial and the parser exactly as a real box's lines would. Acknowledgements
are paced by the loaded exposure. This is how a sim rig runs the projector node without hardware.
"""

from __future__ import annotations

import queue
import threading
import time
import traceback
from typing import Protocol

import serial

from dptpu.nodes.plumbing import backoff_delay_s

from .emulator import TriggerBoxEmulator
from .protocol import (
    Command,
    ProtocolError,
    Reply,
    SequenceSpec,
    encode_command,
    parse_reply,
)

__all__ = ["LinkError", "ProjectorLink"]

_READ_SLICE_S = 0.02


class SerialPort(Protocol):
    """What the link uses of a pyserial port (``serial.serial_for_url``: a real port, or ``loop://``)."""

    timeout: float | None

    @property
    def in_waiting(self) -> int: ...

    def read(self, size: int = 1) -> bytes: ...

    def write(self, data: bytes) -> int | None: ...

    def flush(self) -> None: ...

    def reset_input_buffer(self) -> None: ...

    def close(self) -> None: ...


class LinkError(Exception):
    """The port or the box failed; the message says what to check."""


class ProjectorLink:
    """Owns the serial port of the trigger box in a background thread.

    Parameters
    ----------
    port : str
        Device path (``/dev/ttyACM0``), pty or symlink path, or a pyserial URL (``loop://``).
    sequence : SequenceSpec
        What to ``LOAD`` after each connection.
    logger
        A ``dptpu.graph`` logger (``info``/``warning``/``error`` with ``throttle_duration_sec``).
    on_pattern : callable(scan_id, pattern_index)
        Called (from the link thread) when the box acknowledges a displayed pattern.
    on_scan_end : callable(scan_id, displayed, reason)
        Called once per scan; ``reason`` is ``""`` when every pattern was displayed.
    baudrate : int
    reply_timeout_s : float
        Longest wait for the reply to a command.
    ack_timeout_s : float
        Longest silence during a scan beyond one pattern exposure.
    initial_s, max_s : float
        Reconnection backoff (see :func:`backoff_delay_s`).
    max_waiting : int
        Scan requests that may wait while a scan runs (>= 1); one more is refused.
    """

    def __init__(self, port: str, sequence: SequenceSpec, *, logger, on_pattern, on_scan_end,
                 baudrate: int = 115200, reply_timeout_s: float = 1.0, ack_timeout_s: float = 0.5,
                 initial_s: float = 0.5, max_s: float = 5.0, max_waiting: int = 1):
        if not isinstance(max_waiting, int) or max_waiting < 1:
            raise ValueError(f"max_waiting must be an integer >= 1; got {max_waiting!r}")
        self.port_name = port
        self.sequence = sequence
        self.logger = logger
        self.on_pattern = on_pattern
        self.on_scan_end = on_scan_end
        self.baudrate = baudrate
        self.reply_timeout_s = reply_timeout_s
        self.ack_timeout_s = ack_timeout_s
        self.initial_s = initial_s
        self.max_s = max_s
        self.loopback = port.startswith("loop://")
        self.firmware = ""
        self.garbage_lines = 0        # lines that were not dptpu-trigger/1 replies
        self.connections = 0          # successful handshakes
        self.failures = 0             # connection attempts or sessions that ended in an error
        self._port: SerialPort | None = None
        self._emulator: TriggerBoxEmulator | None = None
        self._buffer = b""
        self._requests: queue.Queue = queue.Queue(maxsize=max_waiting)
        self._new_sequence: SequenceSpec | None = None  # to load before the next scan (load_sequence)
        self._connected = threading.Event()
        self._busy = threading.Event()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="projector-link", daemon=True)

    # --- public, any thread ----------------------------------------------------------------------

    def start(self) -> None:
        self._thread.start()

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=3.0)

    @property
    def connected(self) -> bool:
        """True once ``HELLO`` and ``LOAD`` succeeded, until the port fails."""
        return self._connected.is_set()

    @property
    def busy(self) -> bool:
        """True while a scan runs or one is waiting to run."""
        return self._busy.is_set() or not self._requests.empty()

    def request_scan(self, scan_id: int) -> str:
        """Queue scan ``scan_id``; returns ``""`` when queued, else why not."""
        if not self.connected:
            return f"trigger box on {self.port_name} is not connected (retrying; see the log)"
        try:
            self._requests.put_nowait(scan_id)
        except queue.Full:
            waiting = self._requests.maxsize
            return f"{waiting} scan{'s are' if waiting > 1 else ' is'} already waiting to start"
        return ""

    def load_sequence(self, sequence: SequenceSpec) -> None:
        """Load ``sequence`` (e.g. another exposure) into the box before its next scan; a scan on screen keeps the
        sequence it started with. After a reconnection the box gets ``sequence`` too."""
        self._new_sequence = sequence

    # --- the link thread -------------------------------------------------------------------------

    def _run(self) -> None:
        attempt = 0
        while not self._stop.is_set():
            try:
                self._open()
                self._handshake()
                attempt = 0
                self._serve()
            except LinkError as exc:
                self.failures += 1
                delay_s = backoff_delay_s(attempt, self.initial_s, self.max_s)
                attempt += 1
                self.logger.error(f"trigger box on {self.port_name}: {exc}; retrying in {delay_s:.2f} s "
                                  f"(attempt {attempt})")
                self._close()
                self._stop.wait(delay_s)
            except Exception as exc:  # noqa: BLE001 -- a callback's bug: the thread ending would end every scan
                self.failures += 1
                self.logger.error(f"trigger box on {self.port_name}: {type(exc).__name__} in the link (a bug): {exc}; "
                                  f"reconnecting in {self.initial_s:.2f} s\n{traceback.format_exc()}")
                self._close()
                self._stop.wait(self.initial_s)
            finally:
                self._connected.clear()
        self._close()

    def _open(self) -> None:
        self._close()
        try:
            port: SerialPort = serial.serial_for_url(self.port_name, baudrate=self.baudrate, timeout=_READ_SLICE_S,
                                                     write_timeout=1.0)
        except (serial.SerialException, OSError, ValueError) as exc:
            raise LinkError(f"cannot open the port ({exc}); is the box plugged in, and is the port right?") from None
        self._port = port
        self._buffer = b""
        self._emulator = TriggerBoxEmulator() if self.loopback else None
        try:
            port.reset_input_buffer()
        except (serial.SerialException, OSError):
            pass

    def _close(self) -> None:
        if self._port is not None:
            try:
                self._port.close()
            except (serial.SerialException, OSError):
                pass
            self._port = None

    def _open_port(self) -> SerialPort:
        """The port of the session running now (a session runs between :meth:`_open` and :meth:`_close`)."""
        if self._port is None:
            raise LinkError("the port is not open")
        return self._port

    def _handshake(self) -> None:
        hello = self._command(Command("HELLO"), "HELLO")
        self.firmware = hello.firmware
        loaded = self._command(Command("LOAD", sequence=self.sequence), "LOADED")
        if loaded.count != self.sequence.pattern_count:
            raise LinkError(f"the box loaded {loaded.count} patterns, the sequence has "
                            f"{self.sequence.pattern_count}")
        self.connections += 1
        self._connected.set()
        mode = " (loop://: EMULATED box, no projector)" if self.loopback else ""
        self.logger.info(f"trigger box on {self.port_name}: {hello.protocol} firmware {hello.firmware}, "
                         f"{loaded.count} patterns loaded{mode}")

    def _serve(self) -> None:
        while not self._stop.is_set():
            self._load_new_sequence()
            try:
                scan_id = self._requests.get(timeout=0.05)
            except queue.Empty:
                self._idle_read()
                continue
            self._load_new_sequence()  # set while this request waited
            self._busy.set()
            try:
                self._scan(scan_id)
            finally:
                self._busy.clear()

    def _load_new_sequence(self) -> None:
        """Between scans: ``LOAD`` the sequence :meth:`load_sequence` was given (the handshake's ``LOAD`` again)."""
        sequence, self._new_sequence = self._new_sequence, None
        if sequence is None:
            return
        self.sequence = sequence  # a reconnection loads it too
        loaded = self._command(Command("LOAD", sequence=sequence), "LOADED")
        if loaded.count != sequence.pattern_count:
            raise LinkError(f"the box loaded {loaded.count} patterns, the sequence has {sequence.pattern_count}")
        self.logger.info(f"trigger box on {self.port_name}: {loaded.count} patterns loaded again, exposure "
                         f"{sequence.exposure_us} us")

    def _idle_read(self) -> None:
        """Between scans: notice a vanished port, and count anything the box says unasked."""
        reply = self._read_reply(time.monotonic() + _READ_SLICE_S)
        if reply is not None:
            self.logger.warning(f"trigger box on {self.port_name}: unexpected {reply.kind} line between scans",
                                throttle_duration_sec=5.0)

    def _scan(self, scan_id: int) -> None:
        count = self.sequence.pattern_count
        displayed = 0
        acknowledged: set[int] = set()  # a box may lose an ACK on the line: its pattern got no Trigger
        try:
            self._write(Command("START", scan_id=scan_id))
            started = self._expect("STARTED", time.monotonic() + self.reply_timeout_s, "START")
            if started.kind == "ERR":
                self.on_scan_end(scan_id, 0, f"the box refused START: ERR {started.code} {started.text}".strip())
                return
            silence_s = self.sequence.exposure_us * 1e-6 + self.ack_timeout_s
            while True:
                reply = self._read_reply(time.monotonic() + silence_s)
                if reply is None:
                    raise LinkError(f"no acknowledgement within {silence_s:.3f} s after {displayed} of {count} "
                                    "patterns (box silent)")
                if reply.kind == "ACK" and reply.scan_id == scan_id:
                    if reply.index != displayed:
                        self.logger.warning(f"scan {scan_id}: box acknowledged pattern {reply.index}, "
                                            f"expected {displayed}")
                    displayed = reply.index + 1
                    acknowledged.add(reply.index)
                    self.on_pattern(scan_id, reply.index)
                elif reply.kind == "DONE" and reply.scan_id == scan_id:
                    unacknowledged = sorted(set(range(count)) - acknowledged)
                    reason = "" if displayed == count == reply.count and not unacknowledged else \
                        f"the box reported {reply.count} patterns done, {len(acknowledged)} of {count} acknowledged" \
                        + (f" (no ACK of pattern(s) {', '.join(map(str, unacknowledged[:8]))})" if unacknowledged
                           else "")
                    self.on_scan_end(scan_id, displayed, reason)
                    return
                elif reply.kind == "ABORT" and reply.scan_id == scan_id:
                    self.on_scan_end(scan_id, displayed, f"the box aborted after {reply.count} of {count} patterns: "
                                                         f"{reply.code} {reply.text}".strip())
                    return
                elif reply.kind == "ERR":
                    self.on_scan_end(scan_id, displayed, f"the box reported ERR {reply.code} {reply.text} after "
                                                         f"{displayed} of {count} patterns".strip())
                    return
                else:
                    self.garbage_lines += 1
                    self.logger.warning(f"scan {scan_id}: ignored {reply.kind} line of scan {reply.scan_id}",
                                        throttle_duration_sec=1.0)
        except Exception as exc:  # a LinkError, or a callback's bug: the scan fails with it (traceback: _run's log)
            detail = str(exc) if isinstance(exc, LinkError) else f"{type(exc).__name__}: {exc}"
            self.on_scan_end(scan_id, displayed, f"{displayed} of {count} patterns displayed; {detail}")
            raise

    # --- lines -----------------------------------------------------------------------------------

    def _command(self, command: Command, expected: str) -> Reply:
        self._write(command)
        reply = self._expect(expected, time.monotonic() + self.reply_timeout_s, command.kind)
        if reply.kind == "ERR":
            raise LinkError(f"the box refused {command.kind}: ERR {reply.code} {reply.text}")
        return reply

    def _expect(self, kind: str, deadline: float, sent: str) -> Reply:
        """The next ``kind`` (or ``ERR``) reply before ``deadline``; other replies are counted and skipped."""
        garbage_before = self.garbage_lines
        while True:
            reply = self._read_reply(deadline)
            if reply is None:
                noise = self.garbage_lines - garbage_before
                detail = (f"; {noise} line(s) that were not {kind} arrived instead (wrong baud rate, another "
                          "device, or an echo?)") if noise else "; is the box powered, and on this port?"
                raise LinkError(f"no {kind} reply to {sent} within {self.reply_timeout_s:.2f} s{detail}")
            if reply.kind in (kind, "ERR"):
                return reply
            self.garbage_lines += 1

    def _write(self, command: Command) -> None:
        try:
            port = self._open_port()
            port.write(encode_command(command))
            port.flush()
        except (serial.SerialException, OSError) as exc:
            raise LinkError(f"port lost while writing {command.kind} ({exc})") from None

    def _read_reply(self, deadline: float) -> Reply | None:
        """The next valid reply before ``deadline`` (None on timeout); garbage is counted and logged."""
        while True:
            line = self._read_line(deadline)
            if line is None:
                return None
            if self._emulator is not None and self._feed_echo(self._emulator, line):
                continue
            try:
                return parse_reply(line)
            except ProtocolError as exc:
                self.garbage_lines += 1
                self.logger.warning(f"trigger box on {self.port_name}: ignored line ({exc}); "
                                    f"{self.garbage_lines} so far", throttle_duration_sec=1.0)

    def _feed_echo(self, emulator: TriggerBoxEmulator, line: bytes) -> bool:
        """loop:// only: a line we wrote came back; hand it to the emulator. True if it was a command."""
        head = line.split(b" ", 1)[0].strip()
        if head not in (b"HELLO", b"LOAD", b"START", b"STOP") or (head == b"HELLO" and b" " in line.strip()):
            return False
        emulator.receive(line, time.monotonic())
        return True

    def _read_line(self, deadline: float) -> bytes | None:
        port = self._open_port()
        while b"\n" not in self._buffer:
            now = time.monotonic()
            if self._emulator is not None:
                self._pump_emulator(self._emulator, port, now)
                if b"\n" in self._buffer:  # the emulated box's line went straight into the buffer
                    break
            if now >= deadline:
                return None
            if self._emulator is not None:  # wake for the emulator's next line, not only every read slice
                next_due = self._emulator.next_due()
                wait_s = _READ_SLICE_S if next_due is None else next_due - now
                port.timeout = min(max(wait_s, 0.0005), _READ_SLICE_S, max(deadline - now, 0.0005))
            try:
                chunk = port.read(max(1, port.in_waiting))
            except (serial.SerialException, OSError, TypeError) as exc:
                raise LinkError(f"port lost ({exc}); was the box unplugged?") from None
            self._buffer += chunk
            if len(self._buffer) > 4096 and b"\n" not in self._buffer:
                self.garbage_lines += 1
                self._buffer = b""
                self.logger.warning(f"trigger box on {self.port_name}: 4 KiB without a line end dropped "
                                    "(wrong baud rate?)", throttle_duration_sec=1.0)
        line, self._buffer = self._buffer.split(b"\n", 1)
        return line

    def _pump_emulator(self, emulator: TriggerBoxEmulator, port: SerialPort, now: float) -> None:
        """loop:// only: the emulated box's lines that are due. They go straight into the line buffer when it holds
        no partial line (pyserial's loop:// queues every byte on its own, a cost per byte that adds up over a
        scan's acknowledgements: docs/benchmarks.md), else through the port as a real box's would."""
        for line in emulator.due(now):
            if not self._buffer or self._buffer.endswith(b"\n"):
                self._buffer += line
                continue
            try:
                port.write(line)
            except (serial.SerialException, OSError) as exc:
                raise LinkError(f"loopback port failed ({exc})") from None
