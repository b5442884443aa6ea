"""The scan monitor's /diagnostics (diagnostic_msgs/DiagnosticArray): one array per reported scan, the verdict and
each node's latest ScanStatus, over real sockets (NodeHarness)."""
from __future__ import annotations

import numpy as np

from dptpu.messages import DiagnosticArray, DiagnosticStatus, Header, PointCloud2, ScanStatus, Time
from dptpu.nodes.harness import NodeHarness
from dptpu.nodes.scan_monitor.node import ScanMonitorNode
from dptpu.nodes.scan_monitor.scan_diagnostics import scan_diagnostics

STAMP_NS = 1_700_000_000_000_000_000


def _status(sequence_id, level, state, reason="", **counts) -> ScanStatus:
    return ScanStatus(header=Header(stamp=Time.from_ns(STAMP_NS + 10_000_000)), sequence_id=sequence_id, level=level,
                      state=state, reason=reason, node="/harness_probe", **counts)


def test_each_reported_scan_gives_one_array_with_its_verdict_and_the_nodes_statuses():
    with NodeHarness() as harness:
        harness.start(ScanMonitorNode, ground_truth=False, scan_timeout_s=0.5, status_nodes=["harness_probe"],
                      hardware_id="rig-7")
        status = harness.publisher(ScanStatus, "/scanner/status")
        clouds = harness.publisher(PointCloud2, "/scanner/points")
        diagnostics = harness.collect(DiagnosticArray, "/diagnostics")
        harness.connect()
        points = np.full((2, 3, 3), 0.5, np.float32)
        points[0, 0] = np.nan
        # scan 1: the cloud node's done status (duration 10 ms after the scan's stamp) names the cloud: ok
        status.publish(_status(1, ScanStatus.OK, "done", valid_pixels=5, total_pixels=6, duration_s=0.01))
        clouds.publish(PointCloud2.from_array(points, ("x", "y", "z"),
                                              header=Header(stamp=Time.from_ns(STAMP_NS)), is_dense=False))
        # scan 2: a node fails it
        status.publish(_status(2, ScanStatus.ERROR, "failed", "incomplete after 2 s: received 23 of 24 frames",
                               frames_expected=24, frames_received=23))
        first, second = harness.wait(diagnostics, 2)
    scan, node = first.status
    assert (scan.name, scan.level, scan.hardware_id) == ("dptpu: scan", DiagnosticStatus.OK, "rig-7")
    assert scan.message.startswith("scan 1: ok, 5 points")
    values = {v.key: v.value for v in scan.values}
    assert (values["sequence_id"], values["outcome"], values["valid_points"]) == ("1", "ok", "5")
    assert (node.name, node.level, node.message) == ("dptpu: /harness_probe", DiagnosticStatus.OK, "done")
    assert {v.key: v.value for v in node.values}["valid_pixels"] == "5"
    scan, node = second.status
    assert (scan.level, scan.message) == (
        DiagnosticStatus.ERROR, "scan 2: FAILED: /harness_probe: incomplete after 2 s: received 23 of 24 frames")
    assert (node.level, node.message) == (DiagnosticStatus.ERROR, "incomplete after 2 s: received 23 of 24 frames")
    assert {v.key: v.value for v in node.values}["frames_received"] == "23"


def test_untrusted_scans_warn_and_lost_ones_are_errors():
    for outcome, level in (("untrusted", DiagnosticStatus.WARN), ("lost", DiagnosticStatus.ERROR)):
        array = scan_diagnostics({"sequence_id": 4, "outcome": outcome, "wrong_share": 0.0135,
                                  "node_durations_s": {"/cloud": 0.1}}, "scan 4: ...", [], stamp=Time(sec=5))
        (status,) = array.status
        assert status.level == level and array.header.stamp == Time(sec=5)
        assert [(v.key, v.value) for v in status.values] == [("sequence_id", "4"), ("outcome", outcome),
                                                             ("wrong_share", "0.0135")]


def test_a_unix_time_keeps_its_digits():
    """``cloud_arrival_unix_s`` read 1.79574e+09 (6 significant digits: hours off); now to the millisecond."""
    array = scan_diagnostics({"sequence_id": 4, "outcome": "ok", "cloud_arrival_unix_s": 1795738713.8950314,
                              "latency_ms": 480.62712, "wrong_share": 0.00020152}, "scan 4: ...", [], stamp=Time(sec=5))
    values = {v.key: v.value for v in array.status[0].values}
    assert (values["cloud_arrival_unix_s"], values["latency_ms"], values["wrong_share"]) == (
        "1795738713.895", "480.627", "0.00020152")
