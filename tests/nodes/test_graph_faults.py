"""Faults in the running sim rig (``launch/sim_rig.yaml``, separate processes, 160x120).

- The unwrap process killed mid-run: the launcher respawns it, the scans in flight are reported lost or failed,
  and every later scan is right (scenes change scan by scan, so a scan assembled from two sequences would fail
  the fringe-order bound).
- Malformed bytes injected on the camera and absolute-phase topics: counted by the node (``decode_errors`` in
  its next ScanStatus), logged, no node restarts, and the following scans are right.
"""
from __future__ import annotations

import os
import signal
import time
import uuid
from pathlib import Path

import zmq

from dptpu.graph.discovery import FORMAT, host_identity, process_start_ticks, write_announcement
from dptpu.graph.qos import QoSProfile
from dptpu.graph.transport import pack_envelope
from dptpu.messages import AbsolutePhase, FringeBurst, ScanStatus
from tests.launch_files.running import SIM_RIG, LaunchRun
from tests.nodes.conftest import TEST_DOMAIN_ID
from tests.nodes.test_graph_sim_rig import ORDER_ACCURACY_BOUND, SMALL

NODES = ("projector", "sim", "phase", "unwrap", "cloud", "scan_monitor")


def _ok_scans(run: LaunchRun, after: int = 0) -> list:
    return [s for s in run.scans() if s[2] == "ok" and s[0] > after]


def _accuracy(line: str) -> float:
    return float(line.split("fringe orders ")[1].split(" %")[0]) / 100.0


def _announce_raw_publisher(domain_dir: Path, endpoint: str, topic: str, type_name: str) -> Path:
    """Announce a hand-made publisher of ``topic`` the way any participant does: one JSON file."""
    host, boot_id = host_identity()
    gid = uuid.uuid4().hex
    entry = {"format": FORMAT, "name": "raw_injector", "namespace": "/", "fqn": "/raw_injector", "gid": gid,
             "pid": os.getpid(), "pid_start": process_start_ticks(os.getpid()), "host": host, "boot_id": boot_id,
             "start_time": time.time(), "service_endpoints": [], "curve_public_key": None,
             "publishers": [{"topic": topic, "type": type_name, "gid": uuid.uuid4().hex, "endpoints": [endpoint],
                             "qos": QoSProfile(depth=10).to_dict()}],
             "subscriptions": [], "services": [], "clients": []}
    name = f"n-{os.getpid()}-{gid}.json"
    write_announcement(domain_dir, name, entry)
    return domain_dir / name


def test_malformed_input_is_counted_and_a_killed_unwrap_is_respawned_with_later_scans_right(node_env, probe, tmp_path):
    statuses = probe.subscribe(ScanStatus, "/scanner/status", qos=QoSProfile(depth=500))
    run = LaunchRun(SIM_RIG, "scans:=0", *SMALL, "ply_dir:=", "scan_timeout:=3.0", env=node_env, cwd=tmp_path)
    domain_dir = Path(node_env["DPTPU_DISCOVERY_DIR"]) / f"domain-{TEST_DOMAIN_ID}"
    context = zmq.Context()
    sockets = []
    try:
        run.wait_for(lambda lines: len(_ok_scans(run)) >= 2, 120, "two scans")
        # 1. malformed bytes on the camera's topic (the sim rig's frame bursts: phase, and the cloud keeping frames for
        #    capture_and_save) and the absolute-phase topic (cloud and monitor), each sent once both its subscribers
        #    are connected
        gid = uuid.uuid4().bytes
        for index, (topic, msg_type) in enumerate((("/camera/frame_bursts", FringeBurst),
                                                   ("/scanner/absolute_phase", AbsolutePhase))):
            sock = context.socket(zmq.XPUB)
            sock.setsockopt(zmq.XPUB_VERBOSE, 1)  # every subscriber's subscription, not only the first
            sockets.append(sock)
            endpoint = f"ipc://{domain_dir}/ep/rawinjector{index}"
            sock.bind(endpoint)
            _announce_raw_publisher(domain_dir, endpoint, topic, msg_type.TYPE_NAME)
            deadline = time.monotonic() + 15
            subscribed = 0
            while subscribed < 2 and time.monotonic() < deadline:
                if sock.poll(500):
                    subscribed += sock.recv() == b"\x01" + topic.encode()  # not the shared-memory subscription
            assert subscribed == 2, f"{subscribed} of 2 subscribers connected to the raw publisher of {topic}"
            sock.send_multipart([topic.encode(), b"\x00garbage"])                                   # too few frames
            sock.send_multipart([topic.encode(), b"\xc1 not msgpack", pack_envelope(0, 2, 0, gid)])  # not msgpack
        injected_after = max(s[0] for s in run.scans())
        run.wait_for(lambda lines: len(_ok_scans(run, injected_after + 1)) >= 2, 120, "two scans after the garbage")
        counted = {}
        deadline = time.monotonic() + 10
        while set(counted) != {"/phase", "/cloud"} and time.monotonic() < deadline:
            counted = {}
            for status in list(statuses.messages):
                if status.decode_errors and status.node in ("/phase", "/cloud", "/unwrap"):
                    counted[status.node] = counted.get(status.node, 0) + status.decode_errors
            time.sleep(0.2)
        restarts_before_kill = {name: len(run.pids(name)) for name in NODES}
        # 2. the unwrap process killed
        (unwrap_pid,) = run.pids("unwrap")
        killed_after = max(s[0] for s in run.scans())
        os.killpg(unwrap_pid, signal.SIGKILL)
        run.wait_for(lambda lines: len(run.pids("unwrap")) == 2, 60, "unwrap respawned")
        later = run.wait_for(lambda lines: len(_ok_scans(run, killed_after + 1)) >= 3
                             and _ok_scans(run, killed_after + 1), 120, "three scans after the respawn")
        run.interrupt()
        assert run.wait(timeout=30) == 0
    finally:
        for sock in sockets:
            sock.close(linger=0)
        context.term()
        run.close()
    assert counted.get("/phase") == 2, counted  # the two on /camera/frame_bursts
    assert counted.get("/cloud") == 2, counted  # the two on /scanner/absolute_phase (the monitor counts its own)
    text = run.text(1000)
    assert "malformed message on /camera/frame_bursts" in text
    assert "malformed message on /scanner/absolute_phase" in text
    assert restarts_before_kill == dict.fromkeys(NODES, 1), f"a node restarted after malformed input:\n{text}"
    assert any(f"'unwrap' (pid {unwrap_pid})" in line and "respawning" in line for line in run.lines), text
    assert all(len(run.pids(name)) == 1 for name in NODES if name != "unwrap")
    assert len(later) >= 3
    for sequence_id, _scene, outcome, line in run.scans():
        if outcome == "ok":  # scenes change scan by scan: a scan mixed from two sequences would fail this
            assert _accuracy(line) >= ORDER_ACCURACY_BOUND, line
        else:  # only scans in flight when unwrap died may be missing
            assert killed_after <= sequence_id <= killed_after + 2, line
