"""The projector node as a real process, over real ZeroMQ to a probe node in the test process.

The trigger box is the EMULATOR (``dptpu.nodes.projector.emulator``) on a real pseudo-terminal, run as
its own process and reached through a symlink, so that killing it unplugs the port and restarting it
plugs it back at the same path; or the node's own ``loop://`` mode.
"""

from __future__ import annotations

import signal
import time

import numpy as np

from dptpu.graph import Parameter
from dptpu.graph.interfaces import Trigger as TriggerService
from dptpu.graph.parameter_client import AsyncParameterClient
from dptpu.graph.qos import DurabilityPolicy, QoSProfile
from dptpu.messages import PatternSequence, ScanStatus, Trigger, TriggerBurst

NODE = "dptpu.nodes.projector"
EMULATOR = "dptpu.nodes.projector.emulator"
FAST = ["-p", "reconnect_initial_s:=0.1", "-p", "reconnect_max_s:=0.4", "-p", "reply_timeout_s:=0.5",
        "-p", "ack_timeout_s:=0.3"]


def start_projector(spawn_node, port, *params):
    return spawn_node(NODE, "--ros-args", "-p", f"port:={port}", "-p", "sequence:=8x4,1x3", "-p",
                      "exposure_us:=2000", *FAST, *params)


def call_start_scan(probe, timeout=10.0):
    client = probe.client(TriggerService, "/projector/start_scan")
    assert client.wait_for_service(timeout_sec=timeout)
    return client.call(TriggerService.Request(), timeout_sec=5.0)


def _set(client: AsyncParameterClient, name: str, value):
    future = client.set_parameters([Parameter(name, value=value)])
    assert future.wait(timeout_sec=20), f"no answer to set_parameters {name}"
    return future.result().results[0]


def wait_until(condition, timeout):
    """True as soon as ``condition()`` is, polled every 0.1 s; False after ``timeout`` s."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.1)
    return condition()


def triggers_of(inbox, sequence_id, count=7):
    """``(pattern_index, frequency, steps, step)`` of scan ``sequence_id``'s Triggers, once ``count`` arrived.

    A scan's ScanStatus may overtake its last Triggers: they travel on different sockets.
    """
    try:
        inbox.wait_for(lambda _: sum(t.sequence_id == sequence_id for t in inbox.messages) >= count, timeout=5.0)
    except AssertionError:
        pass  # compared below, with the full list in the message
    return [(t.pattern_index, t.frequency, t.steps, t.step) for t in inbox.messages if t.sequence_id == sequence_id]


EXPECTED = [(0, 8.0, 4, 0), (1, 8.0, 4, 1), (2, 8.0, 4, 2), (3, 8.0, 4, 3), (4, 1.0, 3, 0), (5, 1.0, 3, 1),
            (6, 1.0, 3, 2)]


def test_loop_port_emulates_the_box_service_starts_scans_with_increasing_sequence_ids(spawn_node, probe):
    triggers = probe.subscribe(Trigger, "/projector/trigger")
    status = probe.subscribe(ScanStatus, "/scanner/status")
    node = start_projector(spawn_node, "loop://")
    assert node.wait_for_stderr("7 patterns loaded (loop://: EMULATED box", timeout=15)
    for expected_id in (1, 2):
        response = call_start_scan(probe)
        assert (response.success, response.message) == (True, f"scan {expected_id} queued")
        done = status.wait_for(lambda s, i=expected_id: s.sequence_id == i)
        assert (done.level, done.state, done.frames_expected, done.frames_received) == (ScanStatus.OK, "done", 7, 7)
        assert done.node == "/projector" and done.reason == ""
        assert triggers_of(triggers, expected_id) == EXPECTED
    assert all(t.pattern_count == 7 and t.header.frame_id == "projector" for t in triggers.messages)
    # the sequence is TRANSIENT_LOCAL: a subscriber that comes late still gets it
    sequences = probe.subscribe(PatternSequence, "/projector/pattern_sequence",
                                QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    sequence = sequences.wait(1)[0]
    assert [(e.frequency, e.steps) for e in sequence.entries] == [(8.0, 4), (1.0, 3)]
    assert (sequence.fringe_axis, sequence.projector_size, sequence.shift_sign) == ("x", (912, 1140), -1)


def test_pty_emulator_continuous_scans_survive_garbage_on_the_line(spawn_node, probe, tmp_path):
    triggers = probe.subscribe(Trigger, "/projector/trigger")
    status = probe.subscribe(ScanStatus, "/scanner/status")
    box = spawn_node(EMULATOR, "--link", str(tmp_path / "ttyBOX"), "--garbage-every", "3")
    assert box.wait_event("ready")["device"].startswith("/dev/pts/")
    node = start_projector(spawn_node, tmp_path / "ttyBOX", "-p", "scans:=3")
    finished = status.wait(3, timeout=20)
    assert [(s.sequence_id, s.state, s.frames_received) for s in finished] == [(1, "done", 7), (2, "done", 7),
                                                                               (3, "done", 7)]
    for sequence_id in (1, 2, 3):
        assert triggers_of(triggers, sequence_id) == EXPECTED
    assert node.wait_for_stderr("ignored line (")  # the garbage was seen, logged, and skipped
    lines = [box.wait_event("command")["line"] for _ in range(3)]
    assert lines == ["HELLO", "LOAD x 912 1140 2000 8x4,1x3", "START 1"]
    assert node.proc.poll() is None


def test_port_missing_then_plugged_then_unplugged_mid_scan_then_back(spawn_node, probe, tmp_path):
    link = tmp_path / "ttyBOX"
    triggers = probe.subscribe(Trigger, "/projector/trigger")
    status = probe.subscribe(ScanStatus, "/scanner/status")
    node = start_projector(spawn_node, link, "-p", "exposure_us:=200000")  # 0.2 s a pattern: 1.4 s a scan
    # no port: clear log lines with a growing delay; the node stays up and says why it cannot scan
    assert node.wait_for_stderr("retrying in 0.40 s (attempt 3)", timeout=15)
    assert "cannot open the port" in node.stderr and "retrying in 0.10 s (attempt 1)" in node.stderr
    response = call_start_scan(probe)
    assert not response.success and "is not connected" in response.message
    # plugged in: the node connects by itself
    box = spawn_node(EMULATOR, "--link", str(link))
    box.wait_event("ready")
    assert node.wait_for_stderr("7 patterns loaded", timeout=10)
    assert call_start_scan(probe).success
    triggers.wait(2, timeout=10)
    box.proc.send_signal(signal.SIGKILL)  # unplugged mid-scan
    failed = status.wait(1, timeout=10)[0]
    assert (failed.sequence_id, failed.level, failed.state) == (1, ScanStatus.ERROR, "failed")
    assert 2 <= failed.frames_received < 7 and failed.frames_expected == 7
    assert "patterns displayed; port lost" in failed.reason and failed.reason.startswith("projector: ")
    # back again at the same path: reconnected, and the next scan is complete
    box = spawn_node(EMULATOR, "--link", str(link))
    box.wait_event("ready")
    assert wait_until(lambda: node.stderr.count("7 patterns loaded") == 2, timeout=10)
    assert wait_until(lambda: call_start_scan(probe).success, timeout=10)
    done = status.wait_for(lambda s: s.sequence_id == 2, timeout=15)
    assert (done.state, done.frames_received) == ("done", 7)
    assert triggers_of(triggers, 2) == EXPECTED
    assert node.proc.poll() is None


def test_silent_box_and_partial_sequences_are_reported(spawn_node, probe, tmp_path):
    status = probe.subscribe(ScanStatus, "/scanner/status")
    triggers = probe.subscribe(Trigger, "/projector/trigger")  # the node's own scans wait for a subscriber
    silent = spawn_node(EMULATOR, "--link", str(tmp_path / "silent"), "--silent")
    silent.wait_event("ready")
    quiet = start_projector(spawn_node, tmp_path / "silent", "-r", "__node:=quiet", "-r",
                            "/projector/start_scan:=/quiet/start_scan")
    assert quiet.wait_for_stderr("no HELLO reply to HELLO within 0.50 s; is the box powered, and on this port?",
                                 timeout=15)
    assert quiet.wait_for_stderr("(attempt 2)", timeout=10) and quiet.proc.poll() is None

    aborting = spawn_node(EMULATOR, "--link", str(tmp_path / "abort"), "--abort-after", "5")
    aborting.wait_event("ready")
    start_projector(spawn_node, tmp_path / "abort", "-p", "scans:=1")
    aborted = status.wait(1, timeout=15)[0]
    assert (aborted.state, aborted.level, aborted.frames_received) == ("failed", ScanStatus.ERROR, 5)
    assert triggers_of(triggers, 1, count=5) == EXPECTED[:5]
    assert aborted.reason == ("projector: the box aborted after 5 of 7 patterns: DLP_FAULT pattern 5 not "
                              "confirmed by the DLP")


def test_box_falling_silent_mid_scan_fails_the_scan_and_reconnects(spawn_node, probe, tmp_path):
    status = probe.subscribe(ScanStatus, "/scanner/status")
    probe.subscribe(Trigger, "/projector/trigger")
    hanging = spawn_node(EMULATOR, "--link", str(tmp_path / "hang"), "--hang-after", "3")
    hanging.wait_event("ready")
    node = start_projector(spawn_node, tmp_path / "hang", "-p", "scans:=1")
    failed = status.wait(1, timeout=15)[0]
    assert (failed.sequence_id, failed.state, failed.frames_received) == (1, "failed", 3)
    assert "3 of 7 patterns displayed; no acknowledgement within 0.302 s after 3 of 7 patterns (box silent)" \
        in failed.reason
    assert node.wait_for_stderr("retrying in 0.10 s (attempt 1)", timeout=10)
    assert node.wait_for_stderr("7 patterns loaded", timeout=10)  # the same box answers HELLO again
    assert node.proc.poll() is None


def test_bad_sequence_parameter_exits_with_code_2_naming_it(spawn_node):
    node = spawn_node(NODE, "--ros-args", "-p", "port:=loop://", "-p", "sequence:=96x2")
    assert node.wait(timeout=20) == 2
    assert "sequence entry '96x2' needs frequency > 0 and steps >= 3" in node.stderr


def test_start_requests_wait_up_to_max_waiting_scans_while_a_scan_runs(spawn_node, probe):
    triggers = probe.subscribe(Trigger, "/projector/trigger")
    status = probe.subscribe(ScanStatus, "/scanner/status")
    node = start_projector(spawn_node, "loop://", "-p", "max_waiting_scans:=2", "-p", "exposure_us:=100000")
    assert node.wait_for_stderr("7 patterns loaded", timeout=15)
    assert call_start_scan(probe).success
    triggers.wait_for(lambda t: t.sequence_id == 1)  # scan 1 is on screen (0.7 s): the queue is empty
    responses = [call_start_scan(probe) for _ in range(3)]
    assert [(r.success, r.message) for r in responses[:2]] == [(True, "scan 2 queued"), (True, "scan 3 queued")]
    assert (responses[2].success, responses[2].message) == (False, "2 scans are already waiting to start")
    done = status.wait_for(lambda s: s.sequence_id == 3, timeout=10.0)
    assert (done.state, done.frames_received) == ("done", 7)
    assert sorted({s.sequence_id for s in status.messages}) == [1, 2, 3]  # the refused request started nothing


def test_own_scans_start_at_least_period_s_apart(spawn_node, probe):
    triggers = probe.subscribe(Trigger, "/projector/trigger")
    node = start_projector(spawn_node, "loop://", "-p", "scans:=3", "-p", "period_s:=0.3")
    assert node.wait_for_stderr("started the 3 scan(s)", timeout=20)
    triggers.wait_for(lambda _: sum(t.pattern_index == 0 for t in triggers.messages) >= 3, timeout=5.0)
    firsts = sorted((t.sequence_id, t.header.stamp.to_ns()) for t in triggers.messages if t.pattern_index == 0)
    assert [sequence_id for sequence_id, _ in firsts] == [1, 2, 3]
    gaps_s = np.diff([stamp for _, stamp in firsts]) * 1e-9
    assert (gaps_s > 0.3 - 0.01).all(), gaps_s  # each started one period after the previous one was due


def test_exposure_set_at_run_time_is_loaded_into_the_box_before_the_next_scan(spawn_node, probe, tmp_path):
    """``exposure_us`` was read-only although the issue lists exposure among what applies at run time."""
    triggers = probe.subscribe(Trigger, "/projector/trigger")
    status = probe.subscribe(ScanStatus, "/scanner/status")
    box = spawn_node(EMULATOR, "--link", str(tmp_path / "ttyBOX"))
    assert box.wait_event("ready")["device"].startswith("/dev/pts/")
    node = start_projector(spawn_node, tmp_path / "ttyBOX")
    assert [box.wait_event("command")["line"] for _ in range(2)] == ["HELLO", "LOAD x 912 1140 2000 8x4,1x3"]
    client = AsyncParameterClient(probe.node, "/projector")
    assert client.wait_for_services(timeout_sec=20)
    refused = _set(client, "exposure_us", 50)
    assert (refused.successful, refused.reason) == (
        False, "exposure_us must be an integer in [100, 10000000] microseconds; got 50")
    assert _set(client, "exposure_us", 60_000).successful
    assert box.wait_event("command")["line"] == "LOAD x 912 1140 60000 8x4,1x3"  # at once: the box is idle
    assert node.wait_for_stderr("7 patterns loaded again, exposure 60000 us", timeout=10)
    assert call_start_scan(probe).success
    assert box.wait_event("command")["line"] == "START 1"
    done = status.wait_for(lambda s: s.sequence_id == 1, timeout=10.0)
    assert (done.state, done.frames_received) == ("done", 7)
    # paced by the new exposure: the box ends a scan of 7 patterns of 60 ms no earlier than 0.42 s after it started
    # (it schedules each ACK and its DONE from the START; load only delays them; the old 2000 us: 14 ms of patterns)
    assert done.duration_s >= 7 * 0.060
    assert sorted(t.pattern_index for t in triggers.messages if t.sequence_id == 1) == list(range(7))
    future = client.get_parameters(["exposure_us"])
    assert future.wait(timeout_sec=20) and client.values_of(future.result()) == [60_000]


def bursts_of(inbox, sequence_id, count):
    """The pattern indices of scan ``sequence_id``'s TriggerBursts, once ``count`` of them arrived."""
    try:
        inbox.wait_for(lambda _: sum(b.triggers[0].sequence_id == sequence_id for b in inbox.messages) >= count,
                       timeout=5.0)
    except AssertionError:
        pass  # compared below, with the full list in the message
    return [[t.pattern_index for t in b.triggers] for b in inbox.messages if b.triggers[0].sequence_id == sequence_id]


def test_trigger_bursts_carry_each_entrys_triggers_and_single_triggers_go_only_to_a_listener(spawn_node, probe):
    bursts = probe.subscribe(TriggerBurst, "/projector/trigger_bursts")
    status = probe.subscribe(ScanStatus, "/scanner/status")
    node = start_projector(spawn_node, "loop://", "-p", "trigger_bursts:=true", "-p", "scans:=1")
    assert status.wait(1, timeout=20)[0].state == "done"  # started: the bursts' subscriber counts as a listener
    assert bursts_of(bursts, 1, 2) == [[0, 1, 2, 3], [4, 5, 6]]
    got = [(t.pattern_index, t.frequency, t.steps, t.step) for b in bursts.messages for t in b.triggers]
    assert got == EXPECTED
    for burst in bursts.messages:
        stamps = [t.header.stamp.to_ns() for t in burst.triggers]
        assert stamps == sorted(stamps) and burst.header.stamp == burst.triggers[-1].header.stamp
    triggers = probe.subscribe(Trigger, "/projector/trigger")  # now someone listens to the single Triggers too
    assert wait_until(lambda: triggers.subscription.get_publisher_count() == 1, 10)  # connected to the node
    time.sleep(1.0)  # and the node has had its subscribe event
    assert call_start_scan(probe).success
    assert triggers_of(triggers, 2) == EXPECTED and bursts_of(bursts, 2, 2) == [[0, 1, 2, 3], [4, 5, 6]]
    assert node.proc.poll() is None


def test_a_scan_cut_short_sends_its_last_entrys_triggers_as_they_stand(spawn_node, probe, tmp_path):
    bursts = probe.subscribe(TriggerBurst, "/projector/trigger_bursts")
    status = probe.subscribe(ScanStatus, "/scanner/status")
    aborting = spawn_node(EMULATOR, "--link", str(tmp_path / "abort"), "--abort-after", "6")
    aborting.wait_event("ready")
    start_projector(spawn_node, tmp_path / "abort", "-p", "scans:=1", "-p", "trigger_bursts:=true")
    aborted = status.wait(1, timeout=15)[0]
    assert (aborted.state, aborted.frames_received) == ("failed", 6)
    assert bursts_of(bursts, 1, 2) == [[0, 1, 2, 3], [4, 5]]  # the second entry's two patterns, sent at the abort
