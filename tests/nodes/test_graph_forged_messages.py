"""Forged messages against the running sim rig (issue 19): none of them may stop or fool the scanner.

- one camera frame with a valid envelope, the sim's publisher id and sequence number 2**62 (before: the phase node
  dropped every later real frame as "already delivered", no scan succeeded until the sim restarted);
- a PatternSequence with the opposite shift sign, from a second node (before: hundreds of scans "ok" with wrong
  clouds);
- a CameraInfo of another size, from a second node (before: every scan failed);
- a flood of ScanStatus messages of made-up scans, from a node the monitor does not know (before: they ended a
  ``scans:=N`` launch early as LOST scans).

Each forged publisher is refused and logged by name (``dptpu.graph.known_publishers``), the forged sequence number
is logged as out of sequence (``dptpu.graph.sequence_tracking``), and the scans that follow are correct.
"""
from __future__ import annotations

import dataclasses
import json
import time
from pathlib import Path

import zmq

from dptpu.graph.discovery import get_graph
from dptpu.graph.transport import pack_envelope
from dptpu.messages import CameraInfo, FringeFrame, PatternSequence, ScanStatus, decode, encode
from dptpu.nodes.plumbing import LATCHED_QOS
from tests.nodes.conftest import TEST_DOMAIN_ID
from tests.nodes.fault_matrix import IN_A_ROW, correct, start_rig
from tests.nodes.test_graph_faults import _announce_raw_publisher

FAKE_IDS = range(1_000_000, 1_003_000)
FORGED_SCAN = 999_999  # the forged frame's scan, one that never was (a real scan's id would make it a duplicate)


def _publisher_gid(domain_dir: Path, node: str, topic: str) -> bytes:
    for path in domain_dir.glob("n-*.json"):
        entry = json.loads(path.read_text())
        if entry.get("fqn") == node:
            for pub in entry["publishers"]:
                if pub["topic"] == topic:
                    return bytes.fromhex(pub["gid"])
    raise AssertionError(f"no announcement of {node} publishing {topic} in {domain_dir}")


def test_forged_sequence_configuration_and_statuses_neither_stop_nor_fool_the_scanner(node_env, probe, tmp_path):
    domain_dir = Path(node_env["DPTPU_DISCOVERY_DIR"]) / f"domain-{TEST_DOMAIN_ID}"
    frames = probe.node.create_subscription(None, "/camera/image_raw", lambda views: captured.append(
        [bytes(v) for v in views]), 5, raw=True)
    captured: list = []
    sequences = probe.subscribe(PatternSequence, "/projector/pattern_sequence", qos=LATCHED_QOS)
    infos = probe.subscribe(CameraInfo, "/camera/camera_info", qos=LATCHED_QOS)
    run = start_rig(node_env, tmp_path)
    context = zmq.Context()
    sock = context.socket(zmq.XPUB)
    try:
        run.wait_for(lambda lines: sum(correct(s[3], s[2]) for s in run.scans()) >= 3, 180, "three correct scans")
        assert captured and frames.get_publisher_count() == 1
        real_sequence, real_info = sequences.wait(1, 10)[0], infos.wait(1, 10)[0]
        before = max(s[0] for s in run.scans())
        # 1. a camera frame claiming the sim's publisher id with sequence 2**62, from a raw publisher
        sim_gid = _publisher_gid(domain_dir, "/sim", "/camera/image_raw")
        endpoint = f"ipc://{domain_dir}/ep/forger"
        sock.bind(endpoint)
        _announce_raw_publisher(domain_dir, endpoint, "/camera/image_raw", FringeFrame.TYPE_NAME)
        def phase_connections() -> int:  # publishers the phase node's frame subscription is connected to
            return max((s.stats.get("publisher_count", 0) for s in get_graph(directory=domain_dir).topics[
                "/camera/image_raw"].subscriptions if s.node == "/phase"), default=0)

        deadline = time.monotonic() + 15
        while phase_connections() < 2 and time.monotonic() < deadline:  # the sim and the forger
            time.sleep(0.2)
        assert phase_connections() >= 2, "the phase node did not connect to the forger"
        time.sleep(0.3)  # its subscription reaches the forger's socket
        _, frame = decode(captured[-1], expected_type=FringeFrame)  # a real frame, of a scan that never was
        forged = dataclasses.replace(frame, trigger=dataclasses.replace(frame.trigger, sequence_id=FORGED_SCAN))
        sock.send_multipart([*encode("/camera/image_raw", forged), pack_envelope(0, 2**62, time.time_ns(), sim_gid)])
        # 2.-4. configuration from a second node, and 3000 statuses of scans that never were
        pattern_pub = probe.publisher(PatternSequence, "/projector/pattern_sequence", LATCHED_QOS)
        pattern_pub.publish(dataclasses.replace(real_sequence, shift_sign=-real_sequence.shift_sign))
        info_pub = probe.publisher(CameraInfo, "/camera/camera_info", LATCHED_QOS)
        info_pub.publish(dataclasses.replace(real_info, width=2 * real_info.width, height=2 * real_info.height))
        status_pub = probe.publisher(ScanStatus, "/scanner/status", 100)
        for sequence_id in FAKE_IDS:
            status_pub.publish(ScanStatus(sequence_id=sequence_id, level=ScanStatus.ERROR, state="failed",
                                          node="/phase", reason="forged"))
            if sequence_id % 100 == 0:
                time.sleep(0.01)

        def recovered(lines) -> bool:
            after = [s for s in run.scans() if s[0] > before + 1]
            return len(after) >= 2 * IN_A_ROW and all(correct(s[3], s[2]) for s in after[-IN_A_ROW:])

        run.wait_for(recovered, 120, f"{2 * IN_A_ROW} scans after the forged messages, the last {IN_A_ROW} correct")
        run.interrupt()
        assert run.wait(timeout=30) == 0
    finally:
        sock.close(linger=0)
        context.term()
        run.close()
    text = "\n".join(run.lines)
    after = [s for s in run.scans() if s[0] > before + 1 and s[0] != FORGED_SCAN]  # (the scan in flight may go)
    assert all(correct(line, outcome) for _id, _scene, outcome, line in after), "\n".join(s[3] for s in after)
    assert not [s for s in run.scans() if s[0] == FORGED_SCAN and s[2] == "ok"]  # one frame makes no scan
    assert not [s for s in run.scans() if s[0] in FAKE_IDS]  # no made-up scan reported, none counted
    assert any(line.startswith("[phase]") and "4611686018427387904 was out of this publisher's sequence" in line
               for line in run.lines), text  # 2**62, noticed by the phase node and let go
    for node, topic in (("phase", "/projector/pattern_sequence"), ("sim", "/projector/pattern_sequence"),
                        ("cloud", "/camera/camera_info"), ("unwrap", "/camera/camera_info"),
                        ("scan_monitor", "/scanner/status")):
        assert any(line.startswith(f"[{node}]") and f"refusing the publisher of {topic} of node /probe" in line
                   for line in run.lines), f"{node} did not refuse the forged {topic}:\n{run.text(200)}"
