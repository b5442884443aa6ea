"""Scan monitor: one status line per scan (points, precision and completeness, fringe-order accuracy and depth RMS
against the twin's ground truth, latency), PLY files of the first clouds, and the end of the launch after ``scans``
scans.

The monitor is the sim rig's robot: it subscribes to the clouds and the scan statuses (and, with ground truth, to
the absolute phase and the sim node's truth), reports each scan once, when its cloud arrived (``ok``), when a node
reported it failed (``FAILED``, with the node and the reason), or when nothing more came for ``scan_timeout_s``
(``LOST``). With ground truth a scan whose cloud arrived is ``ok`` only within the bounds ``max_wrong_share`` (the
share of its published points with a wrong fringe order or off the true surface) and ``min_completeness`` (the
share of the truly valid pixels published); otherwise it is ``UNTRUSTED``, with the figure out of bounds
(:func:`dptpu.nodes.scan_monitor.scan_metrics.trust_verdict`); one whose truth (or absolute phase) did not come
within a second of its cloud (a replayed capture without ``gt.npz``) is ``ok (not graded: ...)``, naming what did
not come, and the summary counts them. While two live nodes share the name of one of its
``status_nodes`` (or its own), two graphs run in one domain and their scans mix: every scan whose cloud arrived is
``UNTRUSTED`` with that reason, and the monitor says once what to do (a domain of its own for each graph:
``dptpu launch --domain-id N``; docs/launch.md).
A cloud carries its scan's stamp, not its ``sequence_id``: with ground truth the scan's AbsolutePhase
(same stamp) names it, without it the cloud node's ``done`` ScanStatus does (its ``header.stamp`` minus its
``duration_s`` is the scan's stamp, to the nanosecond; docs/nodes.md), so a monitor without ground truth takes
no full-size map but the clouds. Figures: :mod:`dptpu.nodes.scan_monitor.scan_metrics`. With ``scans:=N`` it
prints a summary after N scans and exits with code 0; in a launch file with ``on_exit: shutdown`` that stops the whole
graph cleanly (docs/launch.md). Run it as ``python -m dptpu.nodes.scan_monitor --ros-args -p scans:=10`` or from
``launch/sim_rig.yaml``. Design: ``docs/scanner.md``.

A line looks like::

    scan 3 sphere: ok, 1,327 points, 0.000 % wrong, 97.8 % complete, fringe orders 100.00 %, depth RMS 0.052 mm
    (0.052 mm where the order is right), latency 184 ms
    scan 1 random-1: UNTRUSTED (5.93 % of the points wrong (> 0.10 %)), 62,110 points, 5.930 % wrong, ...

Latency is from the scan's last frame (the stamp its cloud carries; the sim stamps a frame with its Trigger's
stamp) to the cloud's arrival here.

Topics (defaults; remappable)

============================= ================= ===== ============================================================
topic                         type              dir   notes
============================= ================= ===== ============================================================
``/scanner/points``           PointCloud2       in    the clouds (x, y, z in metres)
``/scanner/status``           ScanStatus        in    failures of every node; the cloud node's names each cloud's scan
``/scanner/absolute_phase``   AbsolutePhase     in    ``ground_truth`` true: for the fringe-order accuracy
``/sim/ground_truth``         AbsolutePhase     in    ``ground_truth`` true: the sim node's truth
``/sim/ground_truth_depth``   Image 32FC1       in    ``ground_truth`` true: the sim node's true depth, metres
``/diagnostics``              DiagnosticArray   out   one per reported scan: the verdict and each node's latest
                                                      ScanStatus (:mod:`.scan_diagnostics`)
``/projector/trigger``        Trigger           in    ``trigger_latency`` true: subscribed once the clouds, the
                                                      statuses (and the absolute phase and truth) have publishers,
                                                      so a projector with ``min_subscribers: 2`` waits for the
                                                      monitor too; gives each scan's first Trigger
``/projector/trigger_bursts`` TriggerBurst      in    instead, with ``trigger_bursts``: an entry's Triggers in one
                                                      message (the projector's ``trigger_bursts:=true``)
============================= ================= ===== ============================================================

Parameters

==================== ======== ==================================================================================
name                 default  meaning
==================== ======== ==================================================================================
``scans``            0        exit (code 0) after this many scans were reported; 0 = run until Ctrl-C
``scan_timeout_s``   5.0      a scan with no cloud and no failure this long after its last message is LOST
``ground_truth``     true     compare with ``/sim/ground_truth``; false: points and latency only (a real rig)
``max_wrong_share``  0.001    with ground truth: a scan with a larger share of wrong points (wrong order or off
                              the surface) among its published points is UNTRUSTED
``min_completeness`` 0.50     with ground truth: a scan publishing a smaller share of the truly valid pixels is
                              UNTRUSTED (defaults and the measurements behind them: docs/scanner.md)
``off_surface_mm``   1.0      a point of the right order is off the surface beyond
                              ``max(off_surface_mm, 6 sigma)`` from the true depth (:mod:`dptpu.fpp.cloud_accuracy`)
``ply_dir``          ""       folder for PLY files of the first ``ply_count`` clouds ("" = none)
``ply_count``        3        clouds written as ``scan_<sequence_id>.ply``
``summary``          ""       JSON file written at exit (and every 50 scans): the last 200 scans' figures, totals
``start_scans``      0        keep this many scans in flight by calling ``start_service`` (scan on demand: the
                              next scan starts when one was reported, so a slow machine is never overrun);
                              0 = start none (the projector runs its own scans)
``start_service``    ``projector/start_scan``  the projector's std_srvs/Trigger service (relative: the projector in
                              the monitor's namespace, ``/projector/start_scan`` at the root)
``start_timeout_s``  2.0      a start request unanswered this long is withdrawn and sent again (a paused or
                              restarted projector loses it), with a warning. After a LOST scan the next start
                              waits until a late message of that scan shows the pipeline moves again, or for
                              a back-off (``scan_timeout_s``, doubling up to 4x), so a paused node costs the
                              scans in flight, not one per ``scan_timeout_s``
``status_nodes``     (below)  the nodes whose ScanStatus messages count, relative names in the monitor's
                              namespace (default ``projector, camera, sim, phase, unwrap, cloud``); another
                              publisher of ``/scanner/status`` is refused and logged, so it can neither fail nor
                              end scans (docs/reliability.md)
``hardware_id``      "dptpu"  ``hardware_id`` of every ``/diagnostics`` status (a real rig: its serial number)
``trigger_latency``  true     take the Triggers (every pattern's) for ``latency_from_first_trigger_ms``; false:
                              clouds and statuses only, as a robot subscribes (``dptpu bench pipeline``'s
                              throughput run: 24 messages a 2 x 12-step scan less; docs/benchmarks.md)
``trigger_bursts``   false    with ``trigger_latency``: take them as the projector's TriggerBursts (an entry's in one
                              message; then the projector sends no single Trigger for the monitor alone)
==================== ======== ==================================================================================

``ground_truth``, ``start_scans``, ``start_service``, ``status_nodes``, ``trigger_latency`` and ``trigger_bursts`` set
the subscriptions
and the client up and are read-only; the others apply at run time (``dptpu param set /scan_monitor
min_completeness 0.6``), checked as at start-up.
"""
from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

import dptpu.graph as rclpy
from dptpu.fpp.cloud_accuracy import OFF_SURFACE_MM
from dptpu.fpp.point_cloud_file import write_point_cloud
from dptpu.graph.interfaces import Trigger as TriggerService
from dptpu.graph.known_publishers import SECOND_GRAPH_ADVICE, SOLE_PUBLISHER, KnownPublishers
from dptpu.graph.node import Node
from dptpu.graph.parameter_rules import ParameterRules, at_least, greater_than, within
from dptpu.graph.processes import process_alive
from dptpu.graph.qos import QoSProfile
from dptpu.graph.subscription import Subscription
from dptpu.graph.task import Future
from dptpu.messages import AbsolutePhase, DiagnosticArray, Image, PointCloud2, ScanStatus, Trigger, TriggerBurst
from dptpu.nodes.node_main import run_node

from .latency_histogram import LatencyHistogram
from .scan_diagnostics import scan_diagnostics
from .scan_metrics import MAX_WRONG_SHARE, MIN_COMPLETENESS, scan_metrics, trust_verdict

__all__ = ["ScanMonitorNode", "main", "summary_json"]

_GRACE_S = 1.0  # how long a scan whose cloud arrived waits for its absolute phase and ground truth
_KEPT_RECORDS = 200  # per-scan records kept for the summary file (totals cover every scan)
_HEARD_RECHECK_S = 1.0  # how long a seen subscriber count of the Triggers is trusted
_STATUS_NODES = ("projector", "camera", "sim", "phase", "unwrap", "cloud")  # ScanStatus publishers counted
_STAMP_MATCH_NS = 1000  # a cloud's stamp and the scan stamp its cloud node's status gives (float64 s) may differ


@dataclass
class _Scan:
    """What arrived of one scan so far."""

    sequence_id: int
    last_message_s: float
    first_trigger_ns: int = 0
    cloud: PointCloud2 | None = None
    cloud_arrival_ns: int = 0
    cloud_arrival_s: float = 0.0
    absolute_phase: AbsolutePhase | None = None
    truth: AbsolutePhase | None = None
    truth_depth: Image | None = None
    seen: dict = field(default_factory=dict)  # node -> state of its OK statuses
    durations_s: dict = field(default_factory=dict)  # node -> ScanStatus.duration_s of its OK status
    cloud_points: tuple | None = None  # (valid_pixels, total_pixels) of the cloud node's done status
    failure: str = ""


class ScanMonitorNode(Node):
    """Reports every scan once (see the module docstring). ``records``: the reported scans' figures."""

    def __init__(self, node_name: str = "scan_monitor", **node_options):
        super().__init__(node_name, **node_options)
        rules = ParameterRules(self)
        wiring = "sets the subscriptions and clients up; restart the node to change it"
        self.scans = rules.settable("scans", 0, check=at_least(0))
        self.scan_timeout_s = rules.settable("scan_timeout_s", 5.0, check=greater_than(0.0))
        self.use_truth = rules.read_only("ground_truth", True, description=wiring)
        self.ply_dir = rules.settable("ply_dir", "")
        self.ply_count = rules.settable("ply_count", 3, check=at_least(0))
        self.summary_path = rules.settable("summary", "", apply=lambda path: setattr(self, "summary_path", path))
        self.start_scans = rules.read_only("start_scans", 0, description=wiring)
        start_service = rules.read_only("start_service", "projector/start_scan", description=wiring)  # in its namespace
        self.trigger_latency = rules.read_only("trigger_latency", True, description=wiring)
        self.trigger_bursts = rules.read_only("trigger_bursts", False, description=wiring)
        status_nodes = tuple(rules.read_only("status_nodes", list(_STATUS_NODES), description=wiring))
        self.start_timeout_s = float(rules.settable("start_timeout_s", 2.0, check=greater_than(0.0)))
        self.max_wrong_share = float(rules.settable("max_wrong_share", MAX_WRONG_SHARE, check=within(0.0, 1.0)))
        self.min_completeness = float(rules.settable("min_completeness", MIN_COMPLETENESS, check=within(0.0, 1.0)))
        self.off_surface_mm = float(rules.settable("off_surface_mm", OFF_SURFACE_MM, check=at_least(0.0)))
        self.hardware_id = rules.settable("hardware_id", "dptpu", description="hardware_id of the /diagnostics")
        if self.start_scans < 0:
            raise ValueError(f"parameter start_scans (0 = none) must be >= 0; got {self.start_scans}")
        self.records: list[dict] = []
        self.reported = 0
        self.counts = {"ok": 0, "untrusted": 0, "failed": 0, "lost": 0}
        self.not_graded = 0  # ground_truth true: scans with a cloud but no figures against the truth
        self._latencies_ms = LatencyHistogram()  # every ok scan's latency, in fixed memory (p50, p99)
        self._pooled: dict[str, float] = {"compared": 0, "errors": 0, "depth_pixels": 0, "depth_squares": 0.0,
                                          "published": 0, "wrong": 0, "truly_valid": 0, "published_truly_valid": 0}
        self.ply_written = 0
        self.finished = False
        self._pending: dict[int, _Scan] = {}
        self._done_ids: dict[int, float] = {}  # reported sequence_id -> when (late messages are ignored)
        self._truths: dict[int, AbsolutePhase] = {}
        self._truth_depths: dict[int, Image] = {}  # stamp ns -> depth image
        self._orphan_clouds: list = []  # (cloud, arrival ns, arrival s) whose scan is not known yet
        self._stamp_ids: dict[int, int] = {}  # scan stamp ns -> sequence_id, from the cloud node's done statuses

        self._node_statuses: dict[str, ScanStatus] = {}  # node -> its latest ScanStatus, for /diagnostics
        self.diagnostics_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self.cloud_sub = self.create_subscription(PointCloud2, "/scanner/points", self.on_cloud, 10)
        self.status_sub = self.create_subscription(ScanStatus, "/scanner/status", self.on_status, QoSProfile(depth=200),
                                                 publishers=KnownPublishers(nodes=status_nodes))
        self.phase_sub: Subscription | None = None
        self.truth_sub: Subscription | None = None
        self.truth_depth_sub: Subscription | None = None
        if self.use_truth:
            self.phase_sub = self.create_subscription(AbsolutePhase, "/scanner/absolute_phase",
                                                      self.on_absolute_phase, 10)
            self.truth_sub = self.create_subscription(AbsolutePhase, "/sim/ground_truth", self.on_truth, 10)
            self.truth_depth_sub = self.create_subscription(Image, "/sim/ground_truth_depth", self.on_truth_depth, 10)
        self.trigger_sub: Subscription | None = None
        self._trigger_topic = self.resolve_topic_name("/projector/trigger")
        self._trigger_bursts_topic = self.resolve_topic_name("/projector/trigger_bursts")
        self._outputs_ready = False  # the clouds and statuses (and truth) have publishers
        self.start_client = self.create_client(TriggerService, start_service) if self.start_scans else None
        self.scans_started = 0
        self._start_call: Future | None = None
        self._start_call_s = 0.0  # monotonic s when _start_call was sent
        self.start_retries = 0  # start requests withdrawn unanswered after start_timeout_s
        # after a LOST scan, no new start until its late messages show the pipeline moves again, or a back-off
        # (scan_timeout_s, doubling to 4x) passed: a paused node costs the scans in flight, not one per timeout
        self._lost_hold: int | None = None  # sequence_id of that LOST scan
        self._starter: frozenset = frozenset()  # (pid, start time) of the node serving start_service
        self._starter_checked_s = -math.inf
        self._hold_until_s = 0.0
        self._hold_s = 0.0
        self._triggers_heard = False
        self._heard_checked_s = -math.inf
        self._progress_s = time.monotonic()
        self.other_graph = ""  # "2 nodes named /cloud (pids 10, 20)" while two graphs share this domain, else ""
        self._other_graph_seen = ""  # what the last check found: it counts once two checks in a row agree
        self._other_graph_checked_s = -math.inf
        self.timer = self.create_timer(0.1, self.on_timer)

    # -- callbacks ------------------------------------------------------------------------------------------

    def on_trigger(self, msg: Trigger) -> None:
        scan = self._scan(msg.sequence_id)
        if scan is not None and not scan.first_trigger_ns:
            scan.first_trigger_ns = msg.header.stamp.to_ns()

    def on_trigger_burst(self, msg: TriggerBurst) -> None:
        """An entry's Triggers: the first names its scan's first pattern when the entry is the scan's first seen."""
        if msg.triggers:
            self.on_trigger(msg.triggers[0])

    def on_cloud(self, msg: PointCloud2) -> None:
        # a cloud carries its scan's stamp, not its sequence_id: the scan is named by the AbsolutePhase of that
        # stamp (ground truth on) or by the cloud node's done status (off); the two topics race
        stamp_ns = msg.header.stamp.to_ns()
        arrival_ns, arrival_s = time.time_ns(), time.monotonic()
        if self.use_truth:
            scan = next((s for s in self._pending.values() if s.absolute_phase is not None
                         and s.absolute_phase.header.stamp.to_ns() == stamp_ns), None)
        else:
            sequence_id = self._id_of_stamp(stamp_ns)
            scan = self._scan(sequence_id) if sequence_id is not None else None
        if scan is None:
            self._orphan_clouds.append((msg, arrival_ns, arrival_s))
            del self._orphan_clouds[:-8]
            return
        self._take_cloud(scan, (msg, arrival_ns, arrival_s))

    def on_absolute_phase(self, msg: AbsolutePhase) -> None:
        scan = self._scan(msg.sequence_id)
        if scan is None:
            return
        scan.absolute_phase = msg
        self._adopt_orphan(scan, msg.header.stamp.to_ns())
        self._try_report(scan)

    def on_truth(self, msg: AbsolutePhase) -> None:
        self._truths[msg.sequence_id] = msg
        while len(self._truths) > 16:
            self._truths.pop(next(iter(self._truths)))
        scan = self._pending.get(msg.sequence_id)
        if scan is not None:
            self._try_report(scan)

    def on_truth_depth(self, msg: Image) -> None:
        self._truth_depths[msg.header.stamp.to_ns()] = msg
        while len(self._truth_depths) > 16:
            self._truth_depths.pop(next(iter(self._truth_depths)))

    def on_status(self, msg: ScanStatus) -> None:
        self._node_statuses[msg.node] = msg
        scan = self._scan(msg.sequence_id)
        if scan is None:
            return
        if msg.level == ScanStatus.ERROR or msg.state == "failed":
            if not scan.failure:
                scan.failure = f"{msg.node}: {msg.reason}"
            self._report(scan)
            return
        scan.seen[msg.node] = msg.state
        scan.durations_s[msg.node] = float(msg.duration_s)
        if not self.use_truth and msg.state == "done" and msg.total_pixels:
            # the cloud node's: stamped when made, duration_s after the scan's stamp (docs/nodes.md)
            stamp_ns = msg.header.stamp.to_ns() - round(float(msg.duration_s) * 1e9)
            scan.cloud_points = (int(msg.valid_pixels), int(msg.total_pixels))  # its finite points, counted there
            self._stamp_ids[stamp_ns] = msg.sequence_id
            while len(self._stamp_ids) > 64:
                self._stamp_ids.pop(next(iter(self._stamp_ids)))
            self._adopt_orphan(scan, stamp_ns, _STAMP_MATCH_NS)
            if scan.cloud is not None:
                self._try_report(scan)

    def on_timer(self) -> None:
        """Report the scans that waited too long; take Triggers once the pipeline's outputs are there."""
        self._check_starter()
        self._check_other_graph()
        if not self._outputs_ready and self.cloud_sub.get_publisher_count() \
                and self.status_sub.get_publisher_count() \
                and all(sub is None or sub.get_publisher_count() for sub in (self.phase_sub, self.truth_sub)):
            self._outputs_ready = True
            if self.trigger_latency and self.trigger_bursts:
                self.trigger_sub = self.create_subscription(TriggerBurst, self._trigger_bursts_topic,
                                                            self.on_trigger_burst, 20, publishers=SOLE_PUBLISHER)
            elif self.trigger_latency:
                self.trigger_sub = self.create_subscription(Trigger, self._trigger_topic, self.on_trigger, 200,
                                                            publishers=SOLE_PUBLISHER)  # made-up scans: refused
            self.get_logger().info("clouds, statuses" + (", absolute phase and ground truth" if self.use_truth else "")
                                   + " have publishers" + (": taking Triggers" if self.trigger_latency else ""))
        now_s = time.monotonic()
        for scan in list(self._pending.values()):
            if (scan.cloud is not None and now_s - scan.cloud_arrival_s > _GRACE_S) \
                    or now_s - scan.last_message_s > self.scan_timeout_s:
                self._report(scan)
        for sequence_id in [i for i, when in self._done_ids.items() if now_s - when > 4 * self.scan_timeout_s]:
            del self._done_ids[sequence_id]
        self._orphan_clouds = [entry for entry in self._orphan_clouds if now_s - entry[2] < self.scan_timeout_s]
        self._start_more()

    # -- scans on demand -------------------------------------------------------------------------------------

    def _start_more(self) -> None:
        """Call ``start_service`` while fewer than ``start_scans`` scans are in flight."""
        if self.start_client is None or not self._outputs_ready or self.finished:
            return
        now_s = time.monotonic()
        if self._start_call is not None:
            if now_s - self._start_call_s < self.start_timeout_s:
                return
            # the request or its answer is lost (projector paused, restarted): withdraw it, send a new one
            self.start_client.remove_pending_request(self._start_call)
            self._start_call = None
            self.start_retries += 1
            self.get_logger().warning(f"start_scan unanswered after {self.start_timeout_s:g} s; asking again "
                                      f"({self.start_retries} retries so far)", throttle_duration_sec=5.0)
        if now_s >= self._heard_checked_s + _HEARD_RECHECK_S:  # a graph snapshot reads all peers: once a second
            # the camera (sim) must hear the Triggers, one by one or as the projector's TriggerBursts (this monitor,
            # when it takes them, is one more subscriber of the Triggers)
            own = 1 if self.trigger_sub is not None else 0
            self._triggers_heard = (self.count_subscribers(self._trigger_topic)
                                    + self.count_subscribers(self._trigger_bursts_topic) - own) >= 1
            self._heard_checked_s = now_s if self._triggers_heard else -math.inf
        if not self._triggers_heard:
            return
        if self.scans_started > self.reported and now_s - self._progress_s > 2 * self.scan_timeout_s:
            self.get_logger().warning(f"{self.scans_started - self.reported} started scan(s) never showed up; "
                                      "starting new ones")
            self.scans_started = self.reported
        if self.scans_started - self.reported >= self.start_scans or not self.start_client.service_is_ready() \
                or now_s < self._hold_until_s:
            return
        self._start_call = call = self.start_client.call_async(TriggerService.Request())
        self._start_call_s = now_s
        call.add_done_callback(self._on_started)

    def _check_starter(self) -> None:
        """Once a second: has the node serving ``start_service`` restarted? A new projector numbers its scans from 1
        again, and the ids this monitor reported recently would make it take the new scans for late messages of
        old ones: forget them."""
        now_s = time.monotonic()
        if self.start_client is None or now_s < self._starter_checked_s + _HEARD_RECHECK_S:
            return
        self._starter_checked_s = now_s
        graph = self._graph()  # the runtime's entries: no file is read
        service = graph.services.get(self.start_client.srv_name)
        servers = set(service.servers) if service is not None else set()
        starter = frozenset((node.pid, node.start_time) for node in graph.nodes
                            if node.fully_qualified_name in servers)
        if starter and self._starter and not starter & self._starter:
            self.get_logger().warning(f"{self.start_client.srv_name} is served by a new process (pid "
                                      f"{', '.join(str(pid) for pid, _ in sorted(starter))}): its scan ids start "
                                      f"again; {len(self._pending)} scan(s) in flight reported lost")
            for scan in list(self._pending.values()):
                self._report(scan)
            self._done_ids.clear()
            self._truths.clear()  # by sequence_id: the new scans' truths come with them
            self.scans_started = self.reported
        if starter:
            self._starter = starter

    def _check_other_graph(self) -> None:
        """Once a second: do two live processes hold a node of the name of one of ``status_nodes`` (or this
        monitor's)? Then a second graph runs in this domain, and the statuses taken may be the other's (the
        older node of a name is the one taken): :attr:`other_graph` says so, and scans are UNTRUSTED meanwhile.

        A respawned node is no second graph: the process of this host that it replaced is left out once it has
        exited (not yet reaped is exited too), and a finding counts only when two checks a second apart agree (a
        killed node's announcement may outlive it by one liveness sweep of discovery)."""
        now_s = time.monotonic()
        if now_s < self._other_graph_checked_s + _HEARD_RECHECK_S:
            return
        self._other_graph_checked_s = now_s
        policy = self.status_sub.known_publishers  # its node names resolved in this monitor's namespace
        watched = {*(policy.nodes if policy is not None else ()), self.get_fully_qualified_name()}
        processes: dict[str, set] = {}
        host = self._runtime.host
        for node in self._graph().nodes:  # the runtime's entries: no file is read
            if node.fully_qualified_name in watched and (node.host != host or process_alive(node.pid)):
                processes.setdefault(node.fully_qualified_name, set()).add((node.host, node.pid))
        found = "; ".join(f"{len(held)} nodes named {name} (pids {', '.join(str(pid) for _, pid in sorted(held))})"
                          for name, held in sorted(processes.items()) if len(held) > 1)
        seen_before, self._other_graph_seen = self._other_graph_seen, found
        if found != seen_before:
            return  # not twice in a row yet
        if found and found != self.other_graph:
            self.get_logger().error(f"two graphs in one domain: {found}; their scans mix, so every scan is UNTRUSTED "
                                    f"while they do. {SECOND_GRAPH_ADVICE}")
        elif self.other_graph and not found:
            self.get_logger().info("one graph in this domain again: scans are graded as before")
        self.other_graph = found

    def _on_started(self, future: Future) -> None:
        if future is not self._start_call:
            return  # a withdrawn call answered late: its scan is counted by its statuses, not here
        self._start_call = None
        try:
            response = future.result()
        except Exception as exc:  # noqa: BLE001 -- a failed call is retried on the next tick
            self.get_logger().warning(f"start_scan failed: {exc}", throttle_duration_sec=5.0)
            return
        if response is not None and response.success:
            self.scans_started += 1
            self._progress_s = time.monotonic()
            self._start_more()

    # -- reporting -------------------------------------------------------------------------------------------

    def _scan(self, sequence_id: int) -> _Scan | None:
        """The pending record of ``sequence_id`` (made on first sight); None once it was reported."""
        if self.finished or sequence_id in self._done_ids:
            if sequence_id == self._lost_hold:  # a late message of the LOST scan: the pipeline moves again
                self._lost_hold, self._hold_until_s, self._hold_s = None, 0.0, 0.0
                self.get_logger().info(f"scan {sequence_id} (reported lost) came on late: starting scans again")
            return None
        scan = self._pending.get(sequence_id)
        if scan is None:
            scan = self._pending[sequence_id] = _Scan(sequence_id, time.monotonic())
        scan.last_message_s = time.monotonic()
        return scan

    def _id_of_stamp(self, stamp_ns: int) -> int | None:
        """The sequence_id whose scan stamp (from the cloud node's done status) is ``stamp_ns``, or None."""
        sequence_id = self._stamp_ids.get(stamp_ns)
        if sequence_id is None:  # a duration of months is not exact in float64 ns
            sequence_id = next((i for stamp, i in self._stamp_ids.items() if abs(stamp - stamp_ns) <= _STAMP_MATCH_NS),
                               None)
        return sequence_id

    def _take_cloud(self, scan: _Scan, entry: tuple) -> None:
        """``entry`` = (cloud, arrival ns, arrival monotonic s) is ``scan``'s cloud."""
        scan.cloud, scan.cloud_arrival_ns, scan.cloud_arrival_s = entry
        scan.last_message_s = max(scan.last_message_s, entry[2])
        self._try_report(scan)

    def _adopt_orphan(self, scan: _Scan, stamp_ns: int, tolerance_ns: int = 0) -> None:
        """Give ``scan`` the cloud of ``stamp_ns`` (within ``tolerance_ns``) that arrived before the scan was known
        (without reporting)."""
        for entry in self._orphan_clouds:
            if abs(entry[0].header.stamp.to_ns() - stamp_ns) <= tolerance_ns:
                self._orphan_clouds.remove(entry)
                scan.cloud, scan.cloud_arrival_ns, scan.cloud_arrival_s = entry
                return

    def _try_report(self, scan: _Scan) -> None:
        if scan.cloud is None:
            return
        if self.use_truth and (scan.absolute_phase is None or self._truth_of(scan) is None
                               or scan.truth_depth is None):
            return
        self._report(scan)

    def _truth_of(self, scan: _Scan):
        truth = self._truths.get(scan.sequence_id)
        if truth is not None:
            scan.truth = truth
            scan.truth_depth = self._truth_depths.get(truth.header.stamp.to_ns())
        return scan.truth

    def _report(self, scan: _Scan) -> None:
        self._pending.pop(scan.sequence_id, None)
        self._done_ids[scan.sequence_id] = time.monotonic()
        record: dict[str, Any] = {"sequence_id": int(scan.sequence_id), "scene": "", "outcome": ""}
        truth = self._truth_of(scan) if self.use_truth else None
        if truth is not None:
            record["scene"] = truth.method.partition(":")[2]
        if scan.cloud is not None:
            record.update(self._figures(scan, scan.cloud, truth))
            record["outcome"] = "ok"
            if self.use_truth and "wrong_share" not in record:
                record["not_graded"] = self._why_not_graded(scan)
                self.not_graded += 1
            if "wrong_share" in record:
                reason = trust_verdict(record["wrong_share"], record["completeness"],
                                       max_wrong_share=self.max_wrong_share, min_completeness=self.min_completeness)
                if reason:
                    record.update(outcome="untrusted", reason=reason)
            if self.other_graph:  # the scan may be the other graph's, whatever its figures
                record.update(outcome="untrusted", reason=f"two graphs in one domain: {self.other_graph}")
            record["node_durations_s"] = dict(scan.durations_s)  # each node's own ScanStatus.duration_s
        elif scan.failure:
            record.update(outcome="failed", reason=scan.failure)
        else:
            arrived = ", ".join(f"{node} {state}" for node, state in scan.seen.items()) or "no status"
            record.update(outcome="lost", reason=f"no cloud within {self.scan_timeout_s:g} s ({arrived})")
        self.counts[record["outcome"]] += 1
        if record["outcome"] == "lost":
            self._hold_s = min(2.0 * self._hold_s if self._hold_s else self.scan_timeout_s, 4.0 * self.scan_timeout_s)
            self._lost_hold, self._hold_until_s = scan.sequence_id, time.monotonic() + self._hold_s
        else:
            self._lost_hold, self._hold_until_s, self._hold_s = None, 0.0, 0.0
        self.reported += 1
        self.scans_started = max(self.scans_started, self.reported)  # a withdrawn start request's scan came after all
        self._pool(record)
        self._progress_s = time.monotonic()
        self.records.append(record)
        del self.records[:-_KEPT_RECORDS]
        line = self._line(record)
        print(line, flush=True)
        self.diagnostics_pub.publish(scan_diagnostics(record, line, self._node_statuses.values(),
                                                      stamp=self.get_clock().now().to_msg(),
                                                      hardware_id=self.hardware_id))
        if scan.cloud is not None and self.ply_dir and self.ply_written < self.ply_count:
            self._write_ply(scan.sequence_id, scan.cloud)
        if self.summary_path and self.reported % 50 == 0:
            self.write_summary()
        if self.scans and self.reported >= self.scans:
            self.finished = True
            print(self.summary_line(), flush=True)
            if self.summary_path:
                self.write_summary()
        self._start_more()

    @staticmethod
    def _why_not_graded(scan: _Scan) -> str:
        """Why a scan with a cloud got no figures against the ground truth (``ground_truth`` true): what did not come
        within the grace after its cloud (a replayed capture without ``gt.npz`` sends no truth), or sizes unlike."""
        missing = [name for name, part in (("ground truth", scan.truth), ("true depth", scan.truth_depth),
                                           ("absolute phase", scan.absolute_phase)) if part is None]
        if missing:
            return f"no {', '.join(missing)} within {_GRACE_S:g} s of its cloud"
        return "its absolute phase, ground truth and cloud differ in size"

    def _figures(self, scan: _Scan, cloud: PointCloud2, truth) -> dict[str, Any]:
        """The figures of ``scan``, whose cloud is ``cloud``."""
        xyz = cloud.to_array(["x", "y", "z"]) if truth is not None else None  # (H, W, 3) metres
        figures: dict[str, Any] = {"latency_ms": (scan.cloud_arrival_ns - cloud.header.stamp.to_ns()) * 1e-6,
                   "cloud_arrival_unix_s": scan.cloud_arrival_ns * 1e-9}
        if scan.first_trigger_ns:
            figures["latency_from_first_trigger_ms"] = (scan.cloud_arrival_ns - scan.first_trigger_ns) * 1e-6
        phase = scan.absolute_phase
        if xyz is not None and scan.truth_depth is not None and phase is not None \
                and phase.absolute_phase.shape == truth.absolute_phase.shape == xyz.shape[:2]:
            same_frequency = math.isclose(phase.frequency, truth.frequency, rel_tol=1e-9)
            metrics = scan_metrics(xyz[..., 2], phase.absolute_phase if same_frequency else np.full_like(
                phase.absolute_phase, np.nan), phase.valid, truth.absolute_phase, truth.valid,
                scan.truth_depth.to_array(), off_surface_mm=self.off_surface_mm)
            figures.update(metrics.as_dict())
            figures["method"] = phase.method
        elif xyz is None and scan.cloud_points is not None \
                and scan.cloud_points[1] == cloud.height * cloud.width:
            # without ground truth: the finite points the cloud node counted (its done status named this cloud)
            figures["valid_points"], figures["total_pixels"] = scan.cloud_points
        else:
            depth_m = xyz[..., 2] if xyz is not None else cloud.to_array(["z"])[..., 0]  # (H, W)
            figures["valid_points"] = int(np.count_nonzero(np.isfinite(depth_m)))
            figures["total_pixels"] = int(depth_m.size)
        return figures

    @staticmethod
    def _line(record: dict) -> str:
        head = f"scan {record['sequence_id']}" + (f" {record['scene']}" if record["scene"] else "")
        if record["outcome"] not in ("ok", "untrusted"):
            return f"{head}: {record['outcome'].upper()}: {record['reason']}"
        verdict = "ok" if record["outcome"] == "ok" else f"UNTRUSTED ({record['reason']})"
        if record.get("not_graded"):
            verdict += f" (not graded: {record['not_graded']})"
        text = f"{head}: {verdict}, {record['valid_points']:,} points"
        if "wrong_share" in record:
            text += f", {100.0 * record['wrong_share']:.3f} % wrong, {100.0 * record['completeness']:.1f} % complete"
        if "order_accuracy" in record:
            text += (f", fringe orders {100.0 * record['order_accuracy']:.2f} %, depth RMS "
                     f"{record['depth_rms_mm']:.3f} mm ({record['depth_rms_right_order_mm']:.3f} mm where the order "
                     f"is right)")
        return text + f", latency {record['latency_ms']:.0f} ms"

    def _pool(self, record: dict) -> None:
        if record["outcome"] not in ("ok", "untrusted"):
            return
        self._latencies_ms.add(record["latency_ms"])
        if record.get("compared_pixels"):
            self._pooled["compared"] += record["compared_pixels"]
            self._pooled["errors"] += record["order_errors"]
        if record.get("depth_pixels"):
            self._pooled["depth_pixels"] += record["depth_pixels"]
            self._pooled["depth_squares"] += record["depth_rms_mm"] ** 2 * record["depth_pixels"]
        if "wrong_points" in record:
            for key, figure in (("published", "valid_points"), ("wrong", "wrong_points"),
                                ("truly_valid", "truly_valid_pixels"),
                                ("published_truly_valid", "published_truly_valid")):
                self._pooled[key] += record[figure]

    def totals(self) -> dict[str, float]:
        """Counts and figures over every reported scan (accuracy and RMS pooled over pixels)."""
        totals: dict[str, float] = dict(self.counts, scans=self.reported)
        if self.not_graded:
            totals["not_graded"] = self.not_graded
        if self._latencies_ms:
            totals["latency_ms_p50"] = self._latencies_ms.percentile(50)
            totals["latency_ms_p99"] = self._latencies_ms.percentile(99)
        pooled = self._pooled
        if pooled["compared"]:
            totals["order_accuracy"] = 1.0 - pooled["errors"] / pooled["compared"]
        if pooled["published"]:
            totals["wrong_share"] = pooled["wrong"] / pooled["published"]
        if pooled["truly_valid"]:
            totals["completeness"] = pooled["published_truly_valid"] / pooled["truly_valid"]
        if pooled["depth_pixels"]:
            totals["depth_rms_mm"] = math.sqrt(pooled["depth_squares"] / pooled["depth_pixels"])
        return totals

    def summary_line(self) -> str:
        t = self.totals()
        text = f"{t['scans']} scans: {t['ok']} ok, {t['untrusted']} untrusted, {t['failed']} failed, {t['lost']} lost"
        if t.get("not_graded"):
            text += f" ({t['not_graded']} with a cloud not graded against the ground truth)"
        if "wrong_share" in t:
            text += f"; {100.0 * t['wrong_share']:.3f} % of the points wrong"
            if "completeness" in t:
                text += f", {100.0 * t['completeness']:.1f} % complete"
        if "order_accuracy" in t:
            text += f"; fringe orders {100.0 * t['order_accuracy']:.3f} %"
        if "depth_rms_mm" in t:
            text += f", depth RMS {t['depth_rms_mm']:.3f} mm"
        if "latency_ms_p50" in t:
            text += f", latency p50 {t['latency_ms_p50']:.0f} ms, p99 {t['latency_ms_p99']:.0f} ms"
        return text

    def write_summary(self) -> None:
        path = Path(self.summary_path)
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            tmp = path.with_name(path.name + ".tmp")
            tmp.write_text(summary_json(self.totals(), self.records))
            tmp.replace(path)
        except OSError as exc:
            self.get_logger().warning(f"cannot write the summary {path}: {exc}")

    def _write_ply(self, sequence_id: int, cloud: PointCloud2) -> None:
        path = Path(self.ply_dir) / f"scan_{sequence_id:08d}.ply"
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            count = write_point_cloud(path, cloud.to_array(["x", "y", "z"]), unit="m",
                                      intensity=cloud.to_array(["intensity"])[..., 0])
        except (OSError, ImportError, RuntimeError, ValueError) as exc:
            self.get_logger().warning(f"PLY {path} failed: {exc}")
            return
        self.ply_written += 1
        print(f"wrote {path} ({count:,} points)", flush=True)


def summary_json(totals: dict, records: list[dict]) -> str:
    """The summary file's text: ``{"totals": ..., "scans": [...]}`` with one scan record a line.

    Written with the C encoder (``json.dumps`` without ``indent``) a piece at a time: the pure-Python encoder that
    ``indent`` selects leaves reference cycles behind on every call, which the node's garbage collector (young
    generation every 5,000 net allocations, :func:`dptpu.nodes.node_main.freeze_startup_objects`) kept for
    thousands of scans.
    """
    scans = ",\n".join(json.dumps(record) for record in records)
    return f'{{"totals": {json.dumps(totals)},\n"scans": [\n{scans}\n]}}\n'


def main(argv=None) -> int:
    """``python -m dptpu.nodes.scan_monitor [--ros-args ...]``: run until ``scans`` were reported (0) or Ctrl-C."""

    def spin(node: ScanMonitorNode) -> None:
        rclpy.get_global_executor().add_node(node)  # once: spin_once then neither adds nor removes it
        while rclpy.ok() and not node.finished:
            rclpy.spin_once(node, timeout_sec=0.1)

    def on_exit(node: ScanMonitorNode) -> None:
        if node.summary_path:
            node.write_summary()
        if not node.finished and node.reported:
            print(node.summary_line(), flush=True)

    # off the hot path, it keeps clouds and truths for a while: freed memory goes back (node_main)
    return run_node("scan_monitor", ScanMonitorNode, argv, spin=spin, on_exit=on_exit, keep_freed=False)

