"""Trigger bursts from outside (issue 20, 20Y): a trigger box that glitches on the wire, as a new user's box may.

The projector runs as a real process with ``trigger_bursts:=true`` against the trigger-box EMULATOR on a real
pseudo-terminal (:class:`~dptpu.nodes.projector.emulator.PtyTriggerBox`, in the test process). A real box's ACK line
can be repeated or lost (noise on the line, a DLP that reports a pattern twice): the emulator is made to do so by a
FAULT INJECTOR on its outgoing lines (named as such; the emulator itself sends every ACK once). The link accepts such
ACKs with a warning, and the single Triggers carry them as they came; the bursts must carry the same Triggers, each
burst of one entry with ``pattern_index`` increasing (the message refuses anything else), the scan with a pattern
never acknowledged must fail naming it, and the node must go on.
"""

from __future__ import annotations

import time
from pathlib import Path

from dptpu.messages import ScanStatus, Trigger, TriggerBurst
from dptpu.nodes.projector.emulator import PtyTriggerBox

REPO_ROOT = Path(__file__).resolve().parents[2]
NODE = "dptpu.nodes.projector"
FAST = ["-p", "reconnect_initial_s:=0.1", "-p", "reconnect_max_s:=0.4", "-p", "reply_timeout_s:=0.5",
        "-p", "ack_timeout_s:=0.3"]


def inject_ack_faults(box: PtyTriggerBox, scan_id: int, repeat: int, lose: int) -> None:
    """FAULT INJECTOR: during scan ``scan_id`` the box sends pattern ``repeat``'s ACK twice and never ``lose``'s."""
    due = box.emulator.due
    repeated, lost = f"ACK {scan_id} {repeat}\n".encode(), f"ACK {scan_id} {lose}\n".encode()

    def faulty_due(now: float) -> list[bytes]:
        lines = []
        for line in due(now):
            if line != lost:
                lines.append(line)
            if line == repeated:
                lines.append(line)
        return lines

    box.emulator.due = faulty_due  # type: ignore[method-assign]


def test_a_repeated_and_a_lost_ack_give_the_single_triggers_order_in_bursts_of_one_entry(spawn_node, probe,
                                                                                         tmp_path):
    bursts = probe.subscribe(TriggerBurst, "/projector/trigger_bursts")
    singles = probe.subscribe(Trigger, "/projector/trigger")
    status = probe.subscribe(ScanStatus, "/scanner/status")
    with PtyTriggerBox(link=tmp_path / "box") as box:
        inject_ack_faults(box, scan_id=1, repeat=2, lose=3)  # 3: the first entry's last pattern (8x4)
        node = spawn_node(NODE, "--ros-args", "-p", f"port:={box.port}", "-p", "sequence:=8x4,1x3", "-p",
                          "exposure_us:=2000", *FAST, "-p", "trigger_bursts:=true", "-p", "scans:=2", "-p",
                          "min_subscribers:=2")
        try:
            first, second = status.wait(2, timeout=20)[:2]
        except AssertionError as exc:
            raise AssertionError(f"{exc}; the projector's stderr:\n{node.stderr}") from None
        # the box reported all 7 done, but pattern 3 got no Trigger (so no frame downstream): not a done scan
        assert (first.sequence_id, first.state, second.sequence_id, second.state) == (1, "failed", 2, "done")
        assert first.reason == "projector: the box reported 7 patterns done, 6 of 7 acknowledged (no ACK of " \
                               "pattern(s) 3)"
        bursts.wait_for(lambda _: sum(b.triggers[0].sequence_id == 2 for b in bursts.messages) >= 2, timeout=10)
        got = {scan: [[t.pattern_index for t in b.triggers] for b in bursts.messages
                      if b.triggers[0].sequence_id == scan] for scan in (1, 2)}
        # scan 1: the repeat starts a new burst (indices must increase), the lost boundary ACK does not merge the
        # first entry's patterns into the second's burst; scan 2: the link thread lived on
        assert got == {1: [[0, 1, 2], [2], [4, 5, 6]], 2: [[0, 1, 2, 3], [4, 5, 6]]}
        singles.wait_for(lambda _: sum(t.sequence_id == 1 for t in singles.messages) >= 7, timeout=10)
        assert [t.pattern_index for t in singles.messages if t.sequence_id == 1] == [0, 1, 2, 2, 4, 5, 6]
        assert node.proc.poll() is None


def test_a_capture_without_ground_truth_replayed_with_ground_truth_true_is_ok_but_said_not_graded(node_env, tmp_path):
    """The sim rig (trigger and frame bursts, its defaults) replays a saved scan without gt.npz, as
    ``~/capture_and_save`` writes a real rig's, with ``ground_truth:=true``: before, every scan said a bare ``ok``
    though nothing was graded (the sim warns once on its own line); the monitor now says it on each scan's line and
    in the summary."""
    from dptpu.fpp.capture import load_ground_truth, read_capture
    from dptpu.sim.image_formation import SequenceSpec
    from dptpu.sim.render import render_capture
    from dptpu.sim.rig import load_twin_rig
    from dptpu.sim.scenes import load_scene
    from tests.launch_files.running import LaunchRun

    rig = load_twin_rig("nominal", size="160x120")
    folder = tmp_path / "saved"
    render_capture(rig, load_scene("sphere", rig), [SequenceSpec(16, 4), SequenceSpec(1, 4)], folder)
    truly_valid = int(load_ground_truth(read_capture(folder)).valid.sum())  # the sphere's pixels the truth decodes
    (folder / "gt.npz").unlink()
    text = (folder / "capture.yaml").read_text()
    (folder / "capture.yaml").write_text(text.replace("ground_truth: gt.npz\n", ""))
    run = LaunchRun(REPO_ROOT / "launch" / "sim_rig.yaml", "scans:=2", "size:=160x120", "sequence:=16x4,1x4",
                    "method:=mf", "model:=none", "ply_dir:=", f"source:={folder}",
                    f"rig:={folder / 'calibration.yaml'}", "ground_truth:=true", env=node_env, cwd=tmp_path)
    try:
        code = run.wait(timeout=180)
    finally:
        run.close()
    assert code == 0, run.text()
    lines = [line for line in run.lines if line.startswith("[scan_monitor] scan ")]
    assert len(lines) == 2, run.text()
    graded_not = "ok (not graded: no ground truth, true depth within 1 s of its cloud), "
    points = {line.partition(graded_not)[2].partition(" points")[0] for line in lines}
    assert all(graded_not in line for line in lines) and len(points) == 1, lines  # the same frames, the same cloud
    # the sphere's cloud: most of the truly valid pixels (graded, the monitor's bound is 50 %), not a pixel more
    assert 0.5 * truly_valid <= int(points.pop().replace(",", "")) <= truly_valid, (lines, truly_valid)
    assert any("2 scans: 2 ok, 0 untrusted, 0 failed, 0 lost (2 with a cloud not graded against the ground truth)"
               in line for line in run.lines), run.text()


def test_the_monitor_line_of_a_scan_not_graded_names_what_did_not_come():
    from dptpu.nodes.scan_monitor.node import ScanMonitorNode

    record = {"sequence_id": 4, "scene": "", "outcome": "ok", "valid_points": 1123, "latency_ms": 21.4,
              "not_graded": "no ground truth, true depth within 1 s of its cloud"}
    assert ScanMonitorNode._line(record) == (
        "scan 4: ok (not graded: no ground truth, true depth within 1 s of its cloud), 1,123 points, latency 21 ms")


def test_own_scans_waiting_for_a_listener_say_so_once_and_start_when_it_comes(spawn_node, probe):
    """``in_flight:=0 projector_scans:=-1 monitor_triggers:=false`` on the sim rig: the projector's own scans wait
    for 2 subscriptions (the sim's and the monitor's, launch/params/projector_sim.yaml) and the monitor takes no
    Triggers; before, no scan ever started and nothing said why."""
    bursts = probe.subscribe(TriggerBurst, "/projector/trigger_bursts")  # the sim: one listener of two
    status = probe.subscribe(ScanStatus, "/scanner/status")
    node = spawn_node(NODE, "--ros-args", "-p", "port:=loop://", "-p", "sequence:=8x4,1x3", "-p",
                      "exposure_us:=2000", *FAST, "-p", "trigger_bursts:=true", "-p", "scans:=1", "-p",
                      "min_subscribers:=2")
    said = "its own scans wait for 2 subscription(s) of /projector/trigger and /projector/trigger_bursts " \
           "(min_subscribers) and have had 1 for 5 s (from /probe): start the missing listener, or lower " \
           "min_subscribers"
    deadline = time.monotonic() + 20
    while said not in node.stderr and time.monotonic() < deadline:
        time.sleep(0.1)
    assert said in node.stderr and not status.messages
    probe.subscribe(Trigger, "/projector/trigger")  # the second listener comes: the scan starts
    assert status.wait(1, timeout=20)[0].state == "done"
    assert [[t.pattern_index for t in b.triggers] for b in bursts.messages] == [[0, 1, 2, 3], [4, 5, 6]]
    assert node.stderr.count("its own scans wait") == 1


class _Log:
    """The link's logger, kept: ``error`` lines in ``errors``."""

    def __init__(self):
        self.errors: list[str] = []

    def info(self, message, **_):
        pass

    def warning(self, message, **_):
        pass

    def error(self, message, **_):
        self.errors.append(message)


def test_a_callback_that_raises_fails_its_scan_and_the_link_goes_on():
    """Before, any exception but a LinkError in ``on_pattern`` (as the repeated ACK's burst raised) ended the link
    thread: that scan never ended and no later scan ran, while the node stayed up saying the box was not connected."""
    import threading

    from dptpu.nodes.projector.link import ProjectorLink
    from dptpu.nodes.projector.protocol import SequenceSpec, parse_sequence_spec

    ended: list[tuple[int, int, str]] = []
    done = threading.Event()

    def on_pattern(scan_id, index):
        if (scan_id, index) == (1, 2):
            raise ValueError("a bug in a callback")

    def on_scan_end(scan_id, displayed, reason):
        ended.append((scan_id, displayed, reason))
        if scan_id == 2:
            done.set()

    log = _Log()
    link = ProjectorLink("loop://", SequenceSpec("x", (912, 1140), 2000, parse_sequence_spec("8x4,1x3"), ()),
                         logger=log, on_pattern=on_pattern, on_scan_end=on_scan_end, initial_s=0.05, max_s=0.1)
    link.start()
    try:
        deadline = time.monotonic() + 10
        while not link.connected and time.monotonic() < deadline:
            time.sleep(0.01)
        assert link.request_scan(1) == ""
        while not (log.errors and link.connected and not link.busy) and time.monotonic() < deadline:
            time.sleep(0.01)
        assert link.request_scan(2) == ""
        assert done.wait(10), (ended, log.errors)
    finally:
        link.close()
    assert ended == [(1, 3, "3 of 7 patterns displayed; ValueError: a bug in a callback"), (2, 7, "")]
    assert "ValueError in the link (a bug): a bug in a callback" in log.errors[0] and "Traceback" in log.errors[0]
