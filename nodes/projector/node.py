"""Projector node: drives the trigger box of a DLP LightCrafter 4500 over a serial port, one Trigger per pattern.

The node loads the pattern sequence given by its parameters into the trigger box (line protocol
``dptpu-trigger/1``, docs/projector-protocol.md), starts a scan on request, and publishes a
:class:`~dptpu.messages.Trigger` the moment the box acknowledges each displayed pattern. Run it as
``python -m dptpu.nodes.projector --ros-args -p port:=/dev/ttyACM0`` or from a launch file
(``pkg: dptpu, exec: projector``).

Topics and services (defaults; remappable):

=================================  ========================  ==============================================
name                               type                      what
=================================  ========================  ==============================================
``/projector/trigger``             Trigger (pub)             one per displayed pattern; ``sequence_id``
                                                             increases by one per scan, from 1
``/projector/trigger_bursts``      TriggerBurst (pub)        with ``trigger_bursts``: an entry's Triggers in one
                                                             message, with its last pattern (Triggers one by one
                                                             then only while ``/projector/trigger`` has
                                                             subscribers)
``/projector/pattern_sequence``    PatternSequence (pub)     the loaded sequence; TRANSIENT_LOCAL, depth 1
``/scanner/status``                ScanStatus (pub)          one per scan: ``done`` (OK) or ``failed``
                                                             (ERROR, with the reason: partial sequence,
                                                             port lost, box silent, box abort)
``~/start_scan``                   std_srvs/Trigger (srv)    queue one scan; ``success`` false, with the
                                                             reason, when the box is not connected or
                                                             ``max_waiting_scans`` scans already wait
=================================  ========================  ==============================================

Parameters:

=======================  =================  ================================================================
name                     default            meaning
=======================  =================  ================================================================
``port``                 ``/dev/ttyACM0``   device path, pty/symlink path, or pyserial URL; ``loop://`` =
                                            no box: the node answers its own echoed commands with the
                                            trigger-box EMULATOR (sim rigs; see ``link``)
``baudrate``             115200             serial speed
``sequence``             ``"96x12,1x12"``   ``frequency x steps`` entries in projection order, then optionally
                                            ``white`` and ``black`` reference frames (the texture)
``fringe_axis``          ``"x"``            ``x`` (vertical stripes, extent = width) or ``y``
``projector_size``       ``[0, 0]``         width, height in projector pixels; ``[0, 0]``: the projector of
                                            ``rig``, or without one a LightCrafter 4500's ``[912, 1140]``
``rig``                  ``""``             a rig file (``dptpu-rig/1`` or OpenCV) whose projector this is: the
                                            panel size is its projector's ``size``, and a ``projector_size``
                                            given too must be the same (else the node refuses to start, naming
                                            both); the sim rig passes the twin's rig, so the patterns follow it
``exposure_us``          8333               display time of one pattern, microseconds (100 .. 10,000,000)
``shift_sign``           -1                 phase step sign of the patterns (-1: the paper's Eq. (1))
``scans``                0                  scans started by the node itself: 0 none (service only),
                                            N > 0 that many, -1 forever
``period_s``             0.0                least time from one scan's start to the next (0: back to back)
``max_waiting_scans``    1                  ``~/start_scan`` requests queued while a scan runs
``min_subscribers``      1                  the node's own scans start only once ``/projector/trigger``
                                            (with ``trigger_bursts``: and ``/projector/trigger_bursts``) has
                                            this many subscriptions (a scan nobody hears is lost)
``trigger_bursts``       false              publish each entry's Triggers as one TriggerBurst (for the sim,
                                            which answers an entry with one FringeBurst: fewer messages a scan)
``frame_id``             ``"projector"``    ``header.frame_id`` of Trigger and PatternSequence
``reply_timeout_s``      1.0                longest wait for a reply to a command
``ack_timeout_s``        0.5                longest silence in a scan beyond one exposure
``reconnect_initial_s``  0.5                first reconnection delay; doubles per failure
``reconnect_max_s``      5.0                longest reconnection delay
=======================  =================  ================================================================

``exposure_us``, ``period_s``, ``min_subscribers`` and ``frame_id`` apply at run time (``dptpu param set``): a new
exposure is loaded into the box (``LOAD`` again) before its next scan; a scan on screen keeps the exposure it started
with. The others are loaded into the box or set the node up at start-up and are read-only.

Convention: a Trigger's stamp is the host time at which the box's ``ACK`` line was read (the box sends it
when the DLP's trigger output marks the pattern on screen; at 115200 baud the line takes about 1 ms).
"""

from __future__ import annotations

import threading
import time
from dataclasses import replace

from dptpu.fpp.calibration import load_rig
from dptpu.graph.interfaces import Trigger as TriggerService
from dptpu.graph.node import Node
from dptpu.graph.parameter_rules import ParameterRules, at_least, frame_id
from dptpu.messages import Header, PatternEntry, PatternSequence, ScanStatus, Trigger, TriggerBurst
from dptpu.nodes.frame_bursts import continues_entry, frames_in_entry
from dptpu.nodes.node_main import run_node
from dptpu.nodes.plumbing import LATCHED_QOS, scan_status

from .link import ProjectorLink
from .protocol import SequenceSpec, parse_sequence_spec, split_references

__all__ = ["DLP4500_SIZE", "ProjectorNode", "main", "panel_size"]

#: Seconds the node's own scans wait for ``min_subscribers`` before it says so, once.
_SUBSCRIBER_WAIT_S = 5.0
#: ``(width, height)`` of the DLP LightCrafter 4500's panel, the projector size without a rig or a size.
DLP4500_SIZE = (912, 1140)


class ProjectorNode(Node):
    """Loads the sequence into the trigger box, runs scans, publishes one Trigger per displayed pattern."""

    def __init__(self, node_name: str = "projector", **kwargs):
        super().__init__(node_name, **kwargs)
        rules = ParameterRules(self)
        box = "loaded into the trigger box at start-up; restart the node to change it"
        port = rules.read_only("port", "/dev/ttyACM0", description=box)
        baudrate = rules.read_only("baudrate", 115200, description=box)
        sequence_text = rules.read_only("sequence", "96x12,1x12", description=box)
        fringe_axis = rules.read_only("fringe_axis", "x", description=box)
        projector_size = rules.read_only("projector_size", [0, 0],
                                         description=box + "; [0, 0]: rig's projector, else a DLP4500's 912x1140")
        rig_path = rules.read_only("rig", "", description="its projector's size is the panel's; " + box)
        exposure_us = rules.settable("exposure_us", 8333, check=self._exposure_problem, apply=self._set_exposure_us,
                                     description="loaded into the trigger box before its next scan")
        self.shift_sign = rules.read_only("shift_sign", -1, description="published in the PatternSequence at start-up")
        self.scans = rules.read_only("scans", 0, description="sets the node's own scan timer up")
        self.period_s = rules.settable("period_s", 0.0, check=at_least(0.0))
        max_waiting = rules.read_only("max_waiting_scans", 1, description=box)
        self.min_subscribers = rules.settable("min_subscribers", 1, check=at_least(0))
        self.frame_id = rules.settable("frame_id", "projector", check=frame_id)
        trigger_bursts = rules.read_only("trigger_bursts", False, description="sets the Triggers' publisher up")
        reply_timeout_s = rules.read_only("reply_timeout_s", 1.0, description=box)
        ack_timeout_s = rules.read_only("ack_timeout_s", 0.5, description=box)
        initial_s = rules.read_only("reconnect_initial_s", 0.5, description=box)
        max_s = rules.read_only("reconnect_max_s", 5.0, description=box)
        if self.shift_sign not in (-1, 1):
            raise ValueError(f"parameter shift_sign must be -1 or +1; got {self.shift_sign}")
        if max_waiting < 1:
            raise ValueError(f"parameter max_waiting_scans must be >= 1; got {max_waiting}")
        fringes, references = split_references(sequence_text)
        self.spec = SequenceSpec(fringe_axis, panel_size(projector_size, rig_path), exposure_us,
                                 parse_sequence_spec(fringes), references)

        self.trigger_pub = self.create_publisher(Trigger, "/projector/trigger", 100)
        self.burst_pub = self.create_publisher(TriggerBurst, "/projector/trigger_bursts", 20) if trigger_bursts \
            else None
        self._entry_triggers: list[Trigger] = []  # the link thread's: the Triggers of the entry on screen
        self.sequence_pub = self.create_publisher(
            PatternSequence, "/projector/pattern_sequence", LATCHED_QOS)
        self.status_pub = self.create_publisher(ScanStatus, "/scanner/status", 20)
        self.start_service = self.create_service(TriggerService, "~/start_scan", self.on_start_scan)
        # checked often enough that a scan starts within 10 ms (or a tenth of the period) of when it is due
        self.auto_timer = self.create_timer(min(0.01, self.period_s / 10) if self.period_s > 0 else 0.01,
                                            self.on_auto_timer) if self.scans else None

        self._scans_lock = threading.Lock()  # the sequence ids and start times (Node's own _lock is the runtime's)
        self._next_sequence_id = 1
        self._scan_started: dict[int, float] = {}   # sequence_id -> monotonic start, for ScanStatus.duration_s
        self._auto_started = 0
        self._next_auto_start = -float("inf")  # monotonic s when the next of the node's own scans is due
        self._waiting_since_s: float | None = None  # monotonic s since the own scans wait for subscribers
        self._wait_said = False
        self.sequence_pub.publish(self.pattern_sequence())
        self.link = ProjectorLink(port, self.spec, logger=self.get_logger(), on_pattern=self.on_pattern,
                                  on_scan_end=self.on_scan_end, baudrate=baudrate, reply_timeout_s=reply_timeout_s,
                                  ack_timeout_s=ack_timeout_s, initial_s=initial_s, max_s=max_s,
                                  max_waiting=max_waiting)
        self.link.start()

    # --- callbacks ---------------------------------------------------------------------------------

    def on_start_scan(self, request, response):
        """``~/start_scan``: queue one scan."""
        sequence_id, reason = self.start_scan()
        response.success = not reason
        response.message = reason or f"scan {sequence_id} queued"
        return response

    def on_auto_timer(self) -> None:
        """Continuous mode: start the next of ``scans`` scans when the box is idle and ``period_s`` has passed."""
        if 0 <= self.scans <= self._auto_started:
            if self.auto_timer is not None:  # the timer that called; made when scans != 0
                self.auto_timer.cancel()
            self.get_logger().info(f"started the {self.scans} scan(s) asked for by the scans parameter")
            return
        now_s = time.monotonic()
        if not self.link.connected or self.link.busy or now_s < self._next_auto_start:
            return
        if self._trigger_subscriptions() < self.min_subscribers:
            self._say_scans_wait(now_s)
            return
        self._waiting_since_s = None
        _, reason = self.start_scan()
        if not reason:
            self._auto_started += 1
            # one period after this scan was due (no drift from the timer's ticks); after now when it was late by
            # a whole period (the box was busy)
            due_s = self._next_auto_start if self._next_auto_start > now_s - self.period_s else now_s
            self._next_auto_start = due_s + self.period_s

    def on_pattern(self, sequence_id: int, pattern_index: int) -> None:
        """Link thread: the box acknowledged pattern ``pattern_index`` of scan ``sequence_id``."""
        frequency, steps, step = self.spec.locate(pattern_index)
        trigger = Trigger(header=self._header(), sequence_id=sequence_id, pattern_index=pattern_index,
                          pattern_count=self.spec.pattern_count, frequency=frequency, steps=steps, step=step,
                          kind=self.spec.kind_of(pattern_index))
        if self.burst_pub is None or self.trigger_pub.get_subscription_count():
            self.trigger_pub.publish(trigger)
        if self.burst_pub is not None:
            if self._entry_triggers and not continues_entry(self._entry_triggers[-1], trigger):
                # a scan cut short, a lost ACK of an entry's last pattern or a repeated ACK: the gathered Triggers
                # go as they stand (one burst never mixes scans or entries, its pattern_index increases)
                self._publish_trigger_burst()
            self._entry_triggers.append(trigger)
            if trigger.step + 1 >= frames_in_entry(trigger):  # the entry's last pattern
                self._publish_trigger_burst()

    def on_scan_end(self, sequence_id: int, displayed: int, reason: str) -> None:
        """Link thread: scan ``sequence_id`` ended after ``displayed`` patterns (``reason`` empty when complete)."""
        if self._entry_triggers:  # a scan cut short: the Triggers of its last entry as they stand
            self._publish_trigger_burst()
        with self._scans_lock:
            started = self._scan_started.pop(sequence_id, time.monotonic())
        if reason:
            self.get_logger().error(f"scan {sequence_id} failed: {reason}")
        self.status_pub.publish(scan_status(
            self, sequence_id, ScanStatus.ERROR if reason else ScanStatus.OK, "failed" if reason else "done",
            f"projector: {reason}" if reason else "", frames_expected=self.spec.pattern_count,
            frames_received=displayed, duration_s=time.monotonic() - started))

    def _exposure_problem(self, exposure_us) -> None:
        """Refuse an exposure the box's sequence cannot take (ValueError: the sequence's own check)."""
        if hasattr(self, "spec"):  # at start-up the sequence is built (and checked) from the parameters
            replace(self.spec, exposure_us=exposure_us)

    def _set_exposure_us(self, exposure_us: int) -> None:
        """``param set /projector exposure_us``: the link loads the sequence with it before the next scan."""
        self.spec = replace(self.spec, exposure_us=exposure_us)
        self.link.load_sequence(self.spec)

    # --- helpers -----------------------------------------------------------------------------------

    def start_scan(self) -> tuple[int, str]:
        """Queue the next scan: ``(sequence_id, "")``, or ``(0, reason)`` when it cannot start."""
        with self._scans_lock:
            sequence_id = self._next_sequence_id
            reason = self.link.request_scan(sequence_id)
            if not reason:
                self._next_sequence_id = sequence_id + 1 if sequence_id < 2**32 - 1 else 1
                self._scan_started[sequence_id] = time.monotonic()
        return (0, reason) if reason else (sequence_id, "")

    def pattern_sequence(self) -> PatternSequence:
        width, height = self.spec.projector_size
        return PatternSequence(header=self._header(), fringe_axis=self.spec.fringe_axis, projector_width=width,
                               projector_height=height, shift_sign=self.shift_sign,
                               entries=[PatternEntry(frequency=f, steps=n) for f, n in self.spec.entries]
                               + [PatternEntry(kind=kind, steps=1) for kind in self.spec.references])

    def _trigger_subscriptions(self) -> int:
        """Subscriptions of the Triggers, one by one and (with ``trigger_bursts``) as bursts: who hears a scan."""
        bursts = self.burst_pub.get_subscription_count() if self.burst_pub is not None else 0
        return self.trigger_pub.get_subscription_count() + bursts

    def _say_scans_wait(self, now_s: float) -> None:
        """The own scans wait for ``min_subscribers``: say once, after :data:`_SUBSCRIBER_WAIT_S`, who listens (a
        listener left out, e.g. the scan monitor at ``monitor_triggers:=false``, stopped the scans without a word)."""
        if self._waiting_since_s is None:
            self._waiting_since_s = now_s
        if self._wait_said or now_s - self._waiting_since_s < _SUBSCRIBER_WAIT_S:
            return
        self._wait_said = True
        topics = ["/projector/trigger"] + (["/projector/trigger_bursts"] if self.burst_pub is not None else [])
        listeners = sorted({info.node for topic in topics for info in self.get_subscriptions_info_by_topic(topic)})
        self.get_logger().warning(
            f"its own scans wait for {self.min_subscribers} subscription(s) of {' and '.join(topics)} "
            f"(min_subscribers) and have had {self._trigger_subscriptions()} for {_SUBSCRIBER_WAIT_S:g} s "
            f"(from {', '.join(listeners) or 'no node'}): start the missing listener, or lower min_subscribers")

    def _publish_trigger_burst(self) -> None:
        """Link thread: publish the entry's Triggers gathered so far as one TriggerBurst."""
        assert self.burst_pub is not None
        triggers, self._entry_triggers = self._entry_triggers, []
        self.burst_pub.publish(TriggerBurst(header=triggers[-1].header, triggers=triggers))

    def _header(self) -> Header:
        return Header(stamp=self.get_clock().now().to_msg(), frame_id=self.frame_id)

    def destroy_node(self):
        self.link.close()
        return super().destroy_node()


def main(argv=None) -> int:
    """``python -m dptpu.nodes.projector [--ros-args ...]``; returns the exit code (2 for bad parameters)."""
    return run_node("projector", ProjectorNode, argv)


def panel_size(projector_size, rig_path: str) -> tuple[int, int]:
    """The projector's ``(width, height)`` from the parameters ``projector_size`` and ``rig``.

    ``[0, 0]`` (not given): the rig's projector ``size``, or :data:`DLP4500_SIZE` without a rig. Given with a
    rig, it must be the rig's: ValueError naming both sizes and what to do otherwise (the scans of a projector
    that is not the rig's would fail one by one in the cloud node, "the scan's projector is 912x1140; the rig's
    is 1024x768").
    """
    given = tuple(int(v) for v in projector_size)
    if len(given) != 2:
        raise ValueError(f"parameter projector_size must be [width, height] (or [0, 0] for the rig's); got "
                         f"{list(projector_size)}")
    if not rig_path:
        return DLP4500_SIZE if given == (0, 0) else (given[0], given[1])
    width, height = (int(v) for v in load_rig(rig_path).projector.size)
    if given not in ((0, 0), (width, height)):
        raise ValueError(f"parameter projector_size is {given[0]}x{given[1]} but the projector of rig {rig_path} is "
                         f"{width}x{height}: leave projector_size out (the rig's is taken) or pass the rig of this "
                         f"projector")
    return width, height
