"""The camera node's acquisition thread: (re)connects the camera and pairs its frames with projector triggers.

Pairing, by trigger mode (``Trigger`` = a pattern the projector says is on screen):

- ``software``: for each Trigger, in arrival order, fire ``TriggerSoftware`` and take the next frame.
  No frame within ``frame_timeout_s`` -> a timeout for that Trigger; three in a row -> camera lost.
- ``hardware``: the projector's trigger output starts each exposure, so frames and Triggers come in the
  same order but over two paths (USB and ZeroMQ) whose latencies differ; either may arrive first. Each
  Trigger is paired with the oldest unpaired frame and vice versa, first in first out. A Trigger with
  no frame after ``frame_timeout_s`` is a timeout; a frame with no Trigger after ``frame_timeout_s`` is
  dropped and counted (``unpaired_frames``).
- ``free-running``: the camera runs at its own rate; each Trigger is paired with the first frame that
  arrives after it. That frame may have started its exposure before the pattern was on screen, so use
  this mode for previews, simulated producers and tests, not for measurement. Frames with no Trigger
  waiting are dropped (or handed on unpaired when ``publish_unpaired`` is set).

Errors that a reconnect can cure (no producer, no device, device lost) close the camera and open it
again after an exponential backoff; the thread never ends on an error. Triggers that arrive while the
camera is not connected are reported as timeouts at once.
"""

from __future__ import annotations

import queue
import threading
import time
from collections import deque

from dptpu.nodes.plumbing import backoff_delay_s

from .genicam_device import CameraSettings, CameraUnavailable, GenICamDevice

__all__ = ["FramePairer", "Acquisition"]

_FETCH_SLICE_S = 0.02
_SOFTWARE_TIMEOUTS_BEFORE_LOSS = 3


class FramePairer:
    """Pairs Triggers with frames for the ``hardware`` and ``free-running`` modes (no I/O, no threads).

    Parameters
    ----------
    mode : str
        ``"hardware"`` or ``"free-running"`` (see the module docstring).
    window_s : float
        How long a Trigger waits for its frame (and, in hardware mode, a frame for its Trigger), seconds.

    All times are ``time.monotonic()`` seconds given by the caller.
    """

    def __init__(self, mode: str, window_s: float):
        if mode not in ("hardware", "free-running"):
            raise ValueError(f"FramePairer mode must be 'hardware' or 'free-running'; got {mode!r}")
        self.mode = mode
        self.window_s = window_s
        self.triggers: deque = deque()   # (trigger, received)
        self.frames: deque = deque()     # (frame, arrived), hardware mode only
        self.unpaired_frames = 0

    def add_trigger(self, trigger, received: float) -> list[tuple]:
        """Register a Trigger; returns ``[(frame, trigger)]`` if a held frame completes a pair."""
        if self.mode == "hardware" and self.frames:
            frame, _ = self.frames.popleft()
            return [(frame, trigger)]
        self.triggers.append((trigger, received))
        return []

    def claimant(self, arrived: float):
        """The Trigger a frame arriving at ``arrived`` pairs with (:meth:`add_frame` takes it), or None: known before
        the frame is copied out of the producer's buffer, so that the copy can go where that Trigger's frame goes."""
        if self.triggers and (self.mode == "hardware" or self.triggers[0][1] <= arrived):
            return self.triggers[0][0]
        return None

    def add_frame(self, frame, arrived: float) -> tuple[list[tuple], bool]:
        """Register a frame: ``([(frame, trigger)], unpaired)``; ``unpaired`` when free-running had no Trigger."""
        if self.triggers and (self.mode == "hardware" or self.triggers[0][1] <= arrived):
            trigger, _ = self.triggers.popleft()
            return [(frame, trigger)], False
        if self.mode == "hardware":
            self.frames.append((frame, arrived))
            return [], False
        self.unpaired_frames += 1
        return [], True

    def expire(self, now: float) -> tuple[list, int]:
        """``(triggers that waited longer than window_s, number of held frames dropped)``."""
        expired = []
        while self.triggers and now - self.triggers[0][1] > self.window_s:
            expired.append(self.triggers.popleft()[0])
        dropped = 0
        while self.frames and now - self.frames[0][1] > self.window_s:
            self.frames.popleft()
            dropped += 1
        self.unpaired_frames += dropped
        return expired, dropped


class Acquisition:
    """The acquisition thread of the camera node.

    Parameters
    ----------
    settings : CameraSettings
    logger
        A ``dptpu.graph`` logger.
    on_frame : callable(frame, stamp_ns, trigger)
        ``frame`` (H, W) uint8/uint16, ``stamp_ns`` host time of arrival (ns since the epoch),
        ``trigger`` the paired Trigger (None for an unpaired free-running frame). Called on this thread.
    on_timeout : callable(trigger, reason)
        A Trigger that got no frame.
    on_connected : callable(device)
        After each successful (re)connection.
    frame_timeout_s : float
    publish_unpaired : bool
    initial_s, max_s : float
        Reconnection backoff.
    allocate : callable(shape, dtype, trigger) -> ndarray, optional
        Where each frame is copied out of the producer's buffer, given the Trigger it will be paired with (None: a
        frame no Trigger claims yet; the node: its row of a burst, or an array loaned by its publisher); default new
        arrays. A frame that is dropped unpublished is simply let go.
    """

    def __init__(self, settings: CameraSettings, *, logger, on_frame, on_timeout, on_connected,
                 frame_timeout_s: float = 1.0, publish_unpaired: bool = False, initial_s: float = 0.5,
                 max_s: float = 5.0, allocate=None):
        self.settings = settings
        self.allocate = allocate
        self.logger = logger
        self.on_frame = on_frame
        self.on_timeout = on_timeout
        self.on_connected = on_connected
        self.frame_timeout_s = frame_timeout_s
        self.publish_unpaired = publish_unpaired
        self.initial_s = initial_s
        self.max_s = max_s
        self.connections = 0
        self.unpaired_frames = 0
        self._last_error = "not connected yet"
        self._triggers: queue.Queue = queue.Queue()
        self._new_settings: queue.Queue = queue.Queue()  # (name, value) for the thread to write
        self._connected = threading.Event()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="camera-acquisition", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=3.0)

    @property
    def connected(self) -> bool:
        return self._connected.is_set()

    def add_trigger(self, trigger) -> None:
        """Any thread: a Trigger arrived (it is stamped with its arrival time here)."""
        self._triggers.put((trigger, time.monotonic()))

    def write_setting(self, name: str, value: float) -> None:
        """Any thread: write ``exposure_us`` or ``frame_rate_hz`` to the camera before its next frame (and at every
        reconnection)."""
        self.settings = self.settings.with_run_time_setting(name, value)
        self._new_settings.put((name, float(value)))

    # --- the thread --------------------------------------------------------------------------------

    def _write_settings(self, device: GenICamDevice) -> None:
        """Write the settings set since the last call (of each, the latest wins)."""
        latest: dict[str, float] = {}
        while True:
            try:
                name, value = self._new_settings.get_nowait()
            except queue.Empty:
                break
            latest[name] = value
        for name, value in latest.items():
            try:
                note = device.write_setting(name, value)
            except (CameraUnavailable, AttributeError, ValueError, OSError) as exc:  # GenICam's errors vary
                note = f"cannot set {name} {value}: {exc}"
            if note:
                self.logger.warning(f"camera: {note}")
            else:
                self.logger.info(f"camera: {name} {value:g}")

    def _run(self) -> None:
        attempt = 0
        while not self._stop.is_set():
            try:
                device = GenICamDevice.open(self.settings)
            except CameraUnavailable as exc:
                attempt = self._back_off(attempt, f"camera: {exc}")
                continue
            attempt = 0
            self.connections += 1
            self._connected.set()
            try:
                self.on_connected(device)
                if self.settings.trigger_mode == "software":
                    self._acquire_software(device)
                else:
                    self._acquire_streaming(device)
            except CameraUnavailable as exc:
                attempt = self._back_off(attempt, f"camera lost: {exc}")
            finally:
                self._connected.clear()
                device.close()

    def _back_off(self, attempt: int, message: str) -> int:
        delay_s = backoff_delay_s(attempt, self.initial_s, self.max_s)
        self._last_error = message
        self.logger.error(f"{message}; retrying in {delay_s:.2f} s (attempt {attempt + 1})")
        deadline = time.monotonic() + delay_s
        while not self._stop.is_set() and time.monotonic() < deadline:
            self._fail_waiting_triggers(f"{message} (reconnecting)")
            self._stop.wait(min(0.05, max(0.0, deadline - time.monotonic())))
        return attempt + 1

    def _fail_waiting_triggers(self, reason: str) -> None:
        while True:
            try:
                trigger, _ = self._triggers.get_nowait()
            except queue.Empty:
                return
            self.on_timeout(trigger, reason)

    def _acquire_software(self, device: GenICamDevice) -> None:
        misses = 0
        while not self._stop.is_set():
            self._write_settings(device)
            try:
                trigger, _ = self._triggers.get(timeout=0.05)
            except queue.Empty:
                continue
            device.software_trigger()
            got = device.fetch(self.frame_timeout_s, allocate=self._destination(lambda claimed=trigger: claimed))
            if got is None:
                misses += 1
                self.on_timeout(trigger, f"no frame within {self.frame_timeout_s:.3f} s of the software trigger")
                if misses >= _SOFTWARE_TIMEOUTS_BEFORE_LOSS:
                    raise CameraUnavailable(f"{misses} software triggers in a row without a frame")
                continue
            misses = 0
            frame, stamp_ns = got
            self.on_frame(frame, stamp_ns, trigger)

    def _destination(self, claimant):
        """The ``allocate`` of one fetch: ``self.allocate`` told the Trigger ``claimant()`` names, or None."""
        if self.allocate is None:
            return None
        allocate = self.allocate
        return lambda shape, dtype: allocate(shape, dtype, claimant())

    def _take_triggers(self, pairer: FramePairer) -> list[tuple]:
        """Hand the Triggers that came since the last call to ``pairer``; the pairs they complete."""
        pairs: list[tuple] = []
        while True:
            try:
                trigger, received = self._triggers.get_nowait()
            except queue.Empty:
                return pairs
            pairs += pairer.add_trigger(trigger, received)

    def _fetch_streaming(self, device: GenICamDevice, pairer: FramePairer) -> tuple[tuple | None, float, list]:
        """``(frame and stamp or None, its arrival, the pairs the Triggers that came while fetch waited complete)``.

        The Triggers are taken once the frame is in and before it is copied out of the producer's buffer (a frame
        pairs only with earlier ones), so that ``allocate`` is told the Trigger the frame will pair with."""
        pairs: list[tuple] = []
        arrivals: list[float] = []

        def claimant():
            arrivals.append(time.monotonic())
            pairs.extend(self._take_triggers(pairer))
            return pairer.claimant(arrivals[0])

        got = device.fetch(_FETCH_SLICE_S, allocate=self._destination(claimant))
        if not arrivals:  # no frame, or no allocate
            claimant()
        return got, arrivals[0], pairs

    def _acquire_streaming(self, device: GenICamDevice) -> None:
        pairer = FramePairer(self.settings.trigger_mode, self.frame_timeout_s)
        while not self._stop.is_set():
            self._write_settings(device)
            got, arrived, pairs = self._fetch_streaming(device, pairer)
            if got is not None:
                frame, stamp_ns = got
                paired, unpaired = pairer.add_frame((frame, stamp_ns), arrived)
                pairs += paired
                if unpaired and self.publish_unpaired:
                    self.on_frame(frame, stamp_ns, None)
            pairs += self._take_triggers(pairer)  # those that came while the frame was copied
            for (frame, stamp_ns), trigger in pairs:
                self.on_frame(frame, stamp_ns, trigger)
            expired, dropped = pairer.expire(time.monotonic())
            for trigger in expired:
                self.on_timeout(trigger, f"no frame within {self.frame_timeout_s:.3f} s of the trigger "
                                         f"({self.settings.trigger_mode})")
            if dropped:
                self.logger.warning(f"camera: dropped {pairer.unpaired_frames} frame(s) so far that no trigger "
                                    f"claimed within {self.frame_timeout_s:.3f} s", throttle_duration_sec=5.0)
            self.unpaired_frames = pairer.unpaired_frames
