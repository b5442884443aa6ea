"""Process supervision: start every node of a plan, copy its output, respawn it, stop it all cleanly.

Life of one launch (:meth:`Supervisor.run`):

1. Every node starts as its own OS process, in its own session and process group, with the launcher's
   environment (``DPTPU_DOMAIN_ID`` and the rest pass through unchanged) plus ``PYTHONUNBUFFERED=1``
   (unless already set) and the node's ``env`` entries. Its stdout and stderr are read by two threads
   and written line by line to the launcher's stdout / stderr as ``[label] line`` (``output: screen``),
   to ``LOG_DIR/label.log`` (``output: log``) or both.
2. When a node exits on its own: exit code 2 is a configuration error (the node could not start with its
   parameters or files: ``dptpu.nodes.node_main``, as argparse) and stops everything, whatever the node's
   ``respawn`` or ``on_exit``, since a restart would fail the same way: the launcher repeats the node's last
   stderr line (its ``NODE: error: ...``) and exits 2. Otherwise a ``required`` node stops everything (the
   launch then exits 1 if the node's exit code was not 0); a ``respawn`` node is restarted after its backoff
   delay (:class:`~dptpu.tools.launch.respawn.RespawnPolicy`); any other node is reported and left exited.
   When no node is running and none is waiting to respawn, the launch ends.
3. Shutdown (SIGINT / SIGTERM / SIGHUP to the launcher, a required node exiting, or everything having
   exited): every process group that still has a live member gets SIGINT; after ``sigint_timeout_s``
   the survivors get SIGTERM; after ``sigterm_timeout_s`` SIGKILL. A second Ctrl-C skips to the next
   signal at once. Defaults (2.0 s + 1.5 s, then SIGKILL) finish well within 5 s, and because whole
   process groups are signalled, helper processes a node started go too.

Exit code of :meth:`Supervisor.run`: 0 after a clean shutdown or when every node has exited, 1 when a
required node failed (exited with a non-zero code or was killed by a signal it was not sent by us), 2 when a
node exited with a configuration error.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TextIO

from .launch_plan import NodeLaunch
from .output_prefix import LastLines, LineSink, start_pipe_reader
from .process_groups import group_alive, signal_group
from .respawn import RespawnPolicy

__all__ = ["Supervisor", "describe_exit", "default_log_dir", "EXIT_CONFIGURATION_ERROR", "EXIT_OK",
           "EXIT_REQUIRED_FAILED"]

EXIT_OK = 0
EXIT_REQUIRED_FAILED = 1
#: A node's exit code when it cannot start with its configuration (bad parameter, unreadable file), and the
#: launch's then: never respawned.
EXIT_CONFIGURATION_ERROR = 2
#: Seconds to wait for a node's last output after it exited, before its message is repeated.
_OUTPUT_DRAIN_S = 1.0
#: Signals that make the launcher shut down (a second one escalates to the next stop signal).
SHUTDOWN_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


def describe_exit(returncode: int | None) -> str:
    """``exited with code 3``, ``was killed by SIGKILL`` or ``could not be started``."""
    if returncode is None:
        return "could not be started"
    if returncode < 0:
        try:
            name = signal.Signals(-returncode).name
        except ValueError:
            name = f"signal {-returncode}"
        return f"was killed by {name}"
    return f"exited with code {returncode}"


def default_log_dir(environ: Mapping[str, str] | None = None) -> str:
    """``$DPTPU_LOG_DIR/launch-YYYYmmdd-HHMMSS-PID`` (default root ``~/.dptpu/log``) for ``output: log``."""
    environ = os.environ if environ is None else environ
    root = environ.get("DPTPU_LOG_DIR") or os.path.join(os.path.expanduser("~"), ".dptpu", "log")
    return os.path.join(root, time.strftime("launch-%Y%m%d-%H%M%S") + f"-{os.getpid()}")


@dataclass
class _Managed:
    """One node and its current process (``None`` between runs)."""

    node: NodeLaunch
    process: subprocess.Popen | None = None
    started_at: float = 0.0
    attempt: int = 0                    # restarts in the current run of quick exits
    respawn_at: float | None = None     # monotonic time of the pending restart
    done: bool = False                  # exited and will not run again
    log: TextIO | None = None
    readers: list[threading.Thread] = field(default_factory=list)
    last_errors: LastLines = field(default_factory=LastLines)  # the current process's last stderr lines


class Supervisor:
    """Runs the nodes of a launch plan as supervised OS processes (see the module docstring).

    Parameters
    ----------
    nodes : sequence of NodeLaunch
        What to start, in order (``LaunchPlan.nodes``).
    stdout, stderr : text streams, optional
        Where prefixed node output goes (default: ``sys.stdout`` / ``sys.stderr``); the launcher's own
        ``[launch] ...`` messages go to ``stderr``.
    log_dir : str, optional
        Folder of ``label.log`` files for nodes with ``output: log`` or ``both`` (default:
        :func:`default_log_dir`, created only when such a node exists).
    env : mapping, optional
        Base environment of every node (default: the launcher's ``os.environ`` at :meth:`run`).
    cwd : str, optional
        Working directory of every node (default: the launcher's).
    sigint_timeout_s, sigterm_timeout_s, sigkill_timeout_s : float
        Seconds to wait after SIGINT, after SIGTERM and after SIGKILL during shutdown.
    stable_after_s : float
        A run at least this long resets a node's respawn backoff.
    """

    def __init__(self, nodes: Sequence[NodeLaunch], *, stdout: TextIO | None = None, stderr: TextIO | None = None,
                 log_dir: str | os.PathLike | None = None, env: Mapping[str, str] | None = None,
                 cwd: str | os.PathLike | None = None, sigint_timeout_s: float = 2.0,
                 sigterm_timeout_s: float = 1.5, sigkill_timeout_s: float = 1.0, stable_after_s: float = 10.0):
        for label, value in (("sigint_timeout_s", sigint_timeout_s), ("sigterm_timeout_s", sigterm_timeout_s),
                             ("sigkill_timeout_s", sigkill_timeout_s)):
            if not 0 <= value < float("inf"):
                raise ValueError(f"{label} must be a finite number of seconds >= 0; got {value}")
        if not 0 < stable_after_s < float("inf"):
            raise ValueError(f"stable_after_s must be a finite number of seconds > 0; got {stable_after_s}")
        labels = [node.label for node in nodes]
        if len(set(labels)) != len(labels):
            raise ValueError(f"node labels must be unique; got {labels}")
        self._managed = [_Managed(node) for node in nodes]
        self._stdout = stdout
        self._stderr = stderr
        self._log_dir: str | None = None if log_dir is None else os.fspath(log_dir)
        self._env = None if env is None else dict(env)
        self._cwd = None if cwd is None else os.fspath(cwd)
        self._timeouts_s = (sigint_timeout_s, sigterm_timeout_s, sigkill_timeout_s)
        self._stable_after_s = stable_after_s
        self._lock = threading.Lock()             # one line at a time on the shared streams
        self._wake = threading.Event()
        self._stop = threading.Event()
        self._escalate = threading.Event()
        self._stop_reason: str | None = None
        self._exit_code = EXIT_OK
        self._groups: list[int] = []               # every process group ever started (pgid = leader pid)
        self._group_labels: dict[int, str] = {}

    # --- public -------------------------------------------------------------------------------

    def request_shutdown(self, reason: str = "shutdown requested") -> None:
        """Ask :meth:`run` to stop everything (thread-safe); a second request escalates to the next signal."""
        if self._stop.is_set():
            self._escalate.set()
        else:
            self._stop_reason = reason
            self._stop.set()
        self._wake.set()

    def current_pids(self) -> dict[str, int]:
        """Label -> pid of every node process running now."""
        return {managed.node.label: managed.process.pid for managed in list(self._managed)
                if managed.process is not None and managed.process.returncode is None}

    def run(self, *, handle_signals: bool = True) -> int:
        """Start every node, supervise until shutdown, stop everything; returns the exit code.

        Parameters
        ----------
        handle_signals : bool
            Install SIGINT / SIGTERM / SIGHUP handlers that call :meth:`request_shutdown` (only possible,
            and only done, in the main thread); the previous handlers are restored on return.

        Returns
        -------
        int
            ``EXIT_OK`` (0) or ``EXIT_REQUIRED_FAILED`` (1).
        """
        previous = {}
        if handle_signals and threading.current_thread() is threading.main_thread():
            for signum in SHUTDOWN_SIGNALS:
                previous[signum] = signal.signal(signum, self._on_signal)
        try:
            self._prepare_log_dir()
            for managed in self._managed:
                if self._stop.is_set():
                    break
                self._start(managed)
            self._supervise()
        finally:
            try:
                self._stop_all()
            finally:
                for signum, handler in previous.items():
                    signal.signal(signum, handler)
                self._finish_output()
        return self._exit_code

    # --- supervision --------------------------------------------------------------------------

    def _on_signal(self, signum, _frame) -> None:
        # only flags here: printing from a signal handler can collide with a print in progress
        self.request_shutdown(f"received {signal.Signals(signum).name}")

    def _say(self, message: str) -> None:
        stream = self._stderr or sys.stderr
        with self._lock:
            try:
                stream.write(f"[launch] {message}\n")
                stream.flush()
            except (OSError, ValueError):
                pass

    def _prepare_log_dir(self) -> None:
        if any(managed.node.output in ("log", "both") for managed in self._managed):
            if self._log_dir is None:
                self._log_dir = default_log_dir(self._env)
            Path(self._log_dir).mkdir(parents=True, exist_ok=True)
            self._say(f"node logs in {self._log_dir}")

    def _supervise(self) -> None:
        while not self._stop.is_set():
            now = time.monotonic()
            for managed in self._managed:
                if managed.process is not None and managed.process.poll() is not None:
                    self._on_exit(managed, managed.process.returncode, now - managed.started_at)
                if self._stop.is_set():
                    break
                if managed.respawn_at is not None and now >= managed.respawn_at:
                    managed.respawn_at = None
                    self._start(managed)
            if self._stop.is_set():
                break
            if all(managed.done for managed in self._managed):
                self._say("every node has exited")
                return
            self._wake.wait(0.02)
            self._wake.clear()
        self._say(f"shutting down ({self._stop_reason})")

    def _start(self, managed: _Managed) -> None:
        node = managed.node
        env = dict(os.environ if self._env is None else self._env)
        env.setdefault("PYTHONUNBUFFERED", "1")  # a Python node's prints reach the prefixer line by line
        env.update(node.env)
        try:
            process = subprocess.Popen(node.command, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                       stderr=subprocess.PIPE, env=env, cwd=self._cwd, start_new_session=True)
        except OSError as exc:
            self._say(f"'{node.label}' could not be started: {exc}")
            managed.started_at = time.monotonic()
            self._on_exit(managed, None, 0.0)
            return
        managed.process = process
        managed.started_at = time.monotonic()
        self._groups.append(process.pid)
        self._group_labels[process.pid] = node.label
        self._say(f"started '{node.label}' (pid {process.pid})")
        if node.output in ("log", "both") and managed.log is None:
            if self._log_dir is None:  # _prepare_log_dir sets it whenever a node logs to a file
                raise RuntimeError(f"no log directory for '{node.label}'")
            # open for the node's life: closed when the node exits (below, where its readers finish)
            managed.log = open(os.path.join(self._log_dir, f"{node.label}.log"), "a", encoding="utf-8")
        screen = node.output in ("screen", "both")
        if process.stdout is None or process.stderr is None:  # Popen was given stdout=PIPE, stderr=PIPE
            raise RuntimeError(f"'{node.label}' was started without output pipes")
        managed.last_errors = LastLines()
        streams = ((process.stdout, self._stdout or sys.stdout, None),
                   (process.stderr, self._stderr or sys.stderr, managed.last_errors))
        for pipe, stream, keep in streams:
            sinks = ([LineSink(stream, prefixed=True)] if screen else []) + \
                    ([LineSink(managed.log, prefixed=False)] if managed.log is not None else []) + \
                    ([keep] if keep is not None else [])
            managed.readers.append(start_pipe_reader(pipe, node.label, sinks, self._lock))

    def _on_exit(self, managed: _Managed, returncode: int | None, run_time_s: float) -> None:
        """A node's process ended while the launch was running: required, respawn, or done."""
        node = managed.node
        pid = managed.process.pid if managed.process is not None else None
        managed.process = None
        what = f"'{node.label}'" + (f" (pid {pid})" if pid is not None else "") + f" {describe_exit(returncode)}"
        if returncode == EXIT_CONFIGURATION_ERROR:
            self._exit_code = EXIT_CONFIGURATION_ERROR
            managed.done = True
            message = self._last_error_line(managed)
            self._say(f"{what}, a configuration error" + (f": {message}" if message else "")
                      + "; not respawned: stopping everything")
            self.request_shutdown(f"'{node.label}' could not start with its configuration")
        elif node.required:
            failed = returncode != 0
            if failed:
                self._exit_code = EXIT_REQUIRED_FAILED
            managed.done = True
            self._say(f"required node {what}: stopping everything")
            self.request_shutdown(f"required node '{node.label}' {describe_exit(returncode)}")
        elif node.respawn:
            policy = RespawnPolicy(node.respawn_delay_s, node.respawn_max_delay_s, self._stable_after_s)
            managed.attempt = policy.next_attempt(managed.attempt, run_time_s)
            delay_s = policy.delay_s(managed.attempt)
            managed.respawn_at = time.monotonic() + delay_s
            self._say(f"{what}; respawning in {delay_s:.2f} s (attempt {managed.attempt})")
        else:
            managed.done = True
            self._say(what)

    def _last_error_line(self, managed: _Managed) -> str:
        """The last line the node's process wrote to stderr (its readers are given a moment to finish)."""
        deadline = time.monotonic() + _OUTPUT_DRAIN_S
        for reader in managed.readers:
            reader.join(timeout=max(0.0, deadline - time.monotonic()))
        return managed.last_errors.lines[-1] if managed.last_errors.lines else ""

    # --- shutdown -------------------------------------------------------------------------------

    def _reap(self) -> None:
        """Collect exit codes of node processes that ended during shutdown (and say so)."""
        for managed in self._managed:
            if managed.process is not None and managed.process.poll() is not None:
                self._say(f"'{managed.node.label}' (pid {managed.process.pid}) "
                          f"{describe_exit(managed.process.returncode)}")
                managed.process = None
                managed.done = True

    def _stop_all(self) -> None:
        self._stop.set()
        for managed in self._managed:
            managed.respawn_at = None
        groups = list(dict.fromkeys(self._groups))
        self._reap()
        for signum, timeout_s in zip((signal.SIGINT, signal.SIGTERM, signal.SIGKILL), self._timeouts_s):
            alive = [pgid for pgid in groups if group_alive(pgid)]
            if not alive:
                break
            names = ", ".join(f"'{self._group_labels[pgid]}'" for pgid in alive)
            self._say(f"sending {signum.name} to {names}")
            for pgid in alive:
                signal_group(pgid, signum)
            deadline = time.monotonic() + timeout_s
            while time.monotonic() < deadline:
                self._reap()
                alive = [pgid for pgid in alive if group_alive(pgid)]
                if not alive:
                    break
                if self._escalate.is_set():
                    self._escalate.clear()
                    break
                time.sleep(0.02)
            self._reap()
        survivors = [pgid for pgid in groups if group_alive(pgid)]
        if survivors:  # only a process that left its group (setsid) or changed user can get here
            self._say(f"process groups still alive after SIGKILL: {survivors}")
        elif groups:
            self._say("all processes stopped")

    def _finish_output(self) -> None:
        deadline = time.monotonic() + 1.0
        for managed in self._managed:
            for reader in managed.readers:
                reader.join(timeout=max(0.0, deadline - time.monotonic()))
        for managed in self._managed:
            if managed.log is not None:
                managed.log.close()
                managed.log = None
