"""Copy a child process's output pipe line by line, each screen line prefixed with ``[label]``.

One daemon thread per pipe reads whole lines (bytes, decoded as UTF-8 with replacement) and writes
each complete line under one shared lock, so lines of different nodes never interleave mid-line.
Screen sinks get ``[label] line``; log-file sinks get the bare line (the file is the node's own).
"""
from __future__ import annotations

import threading
from collections import deque
from typing import IO, TextIO

__all__ = ["LastLines", "LineSink", "start_pipe_reader"]

#: Longest piece of a line copied at once; a longer line is split (memory stays bounded).
_MAX_LINE_BYTES = 65536


class LineSink:
    """Where lines go: a text stream, written with ``prefix`` before each line and flushed per line."""

    def __init__(self, stream: TextIO, *, prefixed: bool):
        self.stream = stream
        self.prefixed = prefixed

    def write_line(self, label: str, line: str) -> None:
        text = f"[{label}] {line}\n" if self.prefixed else f"{line}\n"
        try:
            self.stream.write(text)
            self.stream.flush()
        except (OSError, ValueError):  # a closed terminal or log file must not kill the launcher
            pass


class LastLines(LineSink):
    """Keeps the last ``count`` lines instead of writing them (the message of a node that could not start)."""

    def __init__(self, count: int = 5):
        self.lines: deque[str] = deque(maxlen=count)
        self.prefixed = False

    def write_line(self, label: str, line: str) -> None:
        if line.strip():
            self.lines.append(line)


def _copy_lines(pipe: IO[bytes], label: str, sinks: list[LineSink], lock: threading.Lock) -> None:
    try:
        for raw in iter(lambda: pipe.readline(_MAX_LINE_BYTES), b""):  # a huge line arrives in pieces
            line = raw.decode("utf-8", errors="replace").rstrip("\r\n")
            with lock:
                for sink in sinks:
                    sink.write_line(label, line)
    except (OSError, ValueError):
        pass  # the pipe was closed under us during shutdown
    finally:
        try:
            pipe.close()
        except OSError:
            pass


def start_pipe_reader(pipe: IO[bytes], label: str, sinks: list[LineSink], lock: threading.Lock) -> threading.Thread:
    """Start a daemon thread copying ``pipe`` to ``sinks`` until end of file; returns the thread.

    Parameters
    ----------
    pipe : binary file
        A child's stdout or stderr (``subprocess.PIPE``); closed by the thread at end of file.
    label : str
        The node's label, written as ``[label] `` before each line on prefixed sinks.
    sinks : list of LineSink
        Destinations of every line.
    lock : threading.Lock
        Shared by all readers writing to the same streams.
    """
    thread = threading.Thread(target=_copy_lines, args=(pipe, label, sinks, lock), name=f"launch-output-{label}",
                              daemon=True)
    thread.start()
    return thread
