"""``dptpu record`` and ``dptpu play`` with real processes over real sockets, plus their QoS choices and errors.

End to end: a publisher process (``publish_samples.py``) publishes Images, a PointCloud2, a Trigger and a
TRANSIENT_LOCAL CameraInfo; ``dptpu record`` records them in another process; ``dptpu play --rate 2``
publishes the file again into a second ``dptpu record``; both files must hold the published messages
bit-exactly, the second with the recorded spacing halved.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from mcap.reader import make_reader

from dptpu.cli.main import main as dptpu_main
from dptpu.graph.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from dptpu.tools.recording import McapRecordWriter, describe_mcap, read_mcap, read_metadata
from dptpu.tools.recording.player import PLAYBACK_DEPTH, play, playback_qos
from dptpu.tools.recording.recorder import TOPIC_QOS_METADATA, recording_qos

from .publish_samples import CAMERA_INFO_TOPIC, GAP_S, camera_info, published_messages
from .sample_messages import sample_messages

REPO = Path(__file__).resolve().parents[3]
TOPICS = ["/projector/trigger", "/camera/image_raw", "/scanner/points", CAMERA_INFO_TOPIC]


def _graph_env(tmp_path) -> dict:
    """Environment of a private graph: its own discovery folder, same-host ipc, no peers."""
    env = {key: value for key, value in os.environ.items()
           if not key.startswith("DPTPU_") and key not in ("ROS_DOMAIN_ID",)}
    env["DPTPU_DISCOVERY_DIR"] = str(tmp_path / "graph")
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPO), env.get("PYTHONPATH", "")]))
    return env


def _dptpu(*args) -> list[str]:
    return [sys.executable, "-m", "dptpu.cli.main", *map(str, args)]


def _stop(process: subprocess.Popen) -> None:
    if process.poll() is None:
        process.kill()
        process.wait(timeout=5)


# --------------------------------------------------------------------------------------------------
# End to end
# --------------------------------------------------------------------------------------------------

def test_record_then_play_end_to_end(tmp_path):
    env = _graph_env(tmp_path)
    first, second = tmp_path / "first.mcap", tmp_path / "second.mcap"
    expected = [(CAMERA_INFO_TOPIC, camera_info()), *published_messages()]
    publisher = subprocess.Popen([sys.executable, "-m", "tests.tools.recording.publish_samples"], cwd=REPO, env=env,
                                 stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    replay_recorder = None
    try:
        recorded = subprocess.run(_dptpu("record", "-o", first, *TOPICS, "--max-messages", len(expected),
                                         "--duration", 20), cwd=REPO, env=env, capture_output=True, text=True,
                                  timeout=40)
        assert publisher.wait(timeout=20) == 0, publisher.stdout.read()
        assert recorded.returncode == 0, recorded.stderr
        assert f"recorded {len(expected)} message(s)" in recorded.stdout and "stopped: max_messages" in recorded.stdout
        assert "[record] subscribed to /camera/image_raw [sensor_msgs/msg/Image]" in recorded.stderr

        records = list(read_mcap(first))
        # the CameraInfo was published before the recorder existed: TRANSIENT_LOCAL delivered it
        assert [(r.topic, r.message) for r in records] == expected
        qos = read_metadata(first)[TOPIC_QOS_METADATA]
        assert '"durability": "transient_local"' in qos[CAMERA_INFO_TOPIC]
        assert '"durability": "volatile"' in qos["/camera/image_raw"]
        with open(first, "rb") as stream:  # and as rosbag2 reads it: each channel's offered_qos_profiles
            offered = {channel.topic: channel.metadata["offered_qos_profiles"]
                       for channel in make_reader(stream).get_summary().channels.values()}
        assert "  reliability: 1\n  durability: 1\n" in offered[CAMERA_INFO_TOPIC]  # reliable, transient local
        assert "  reliability: 1\n  durability: 2\n" in offered["/camera/image_raw"]  # reliable, volatile
        image_times = [r.log_time_ns for r in records if r.topic == "/camera/image_raw"]
        first_gaps_s = [(b - a) / 1e9 for a, b in zip(image_times, image_times[1:])]
        assert all(0.5 * GAP_S < gap < 3 * GAP_S for gap in first_gaps_s), first_gaps_s

        replay_recorder = subprocess.Popen(_dptpu("record", "-o", second, *TOPICS, "--max-messages", len(expected),
                                                  "--duration", 20),
                                           cwd=REPO, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        played = subprocess.run(_dptpu("play", first, "--rate", 2, "--wait-for-subscribers", 15), cwd=REPO, env=env,
                                capture_output=True, text=True, timeout=40)
        assert played.returncode == 0, played.stderr
        assert f"published {len(expected)} message(s)" in played.stdout
        out, err = replay_recorder.communicate(timeout=30)
        assert replay_recorder.returncode == 0, err
        replayed = list(read_mcap(second))
        assert sorted((r.topic, r.message.header.stamp.to_ns()) for r in replayed) == sorted(
            (topic, msg.header.stamp.to_ns()) for topic, msg in expected)
        for topic in TOPICS:
            assert [r.message for r in replayed if r.topic == topic] == [m for t, m in expected if t == topic]
        replay_times = [r.log_time_ns for r in replayed if r.topic == "/camera/image_raw"]
        recorded_span_s = (image_times[-1] - image_times[0]) / 1e9  # about 2 * GAP_S
        replay_span_s = (replay_times[-1] - replay_times[0]) / 1e9
        assert abs(replay_span_s - recorded_span_s / 2) < 0.06, (recorded_span_s, replay_span_s)  # --rate 2
    finally:
        _stop(publisher)
        if replay_recorder is not None:
            _stop(replay_recorder)


def test_record_stops_on_sigint_with_a_complete_file(tmp_path):
    env = _graph_env(tmp_path)
    path = tmp_path / "interrupted.mcap"
    recorder = subprocess.Popen(_dptpu("record", "-o", path, "/never/published"), cwd=REPO, env=env,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 10
        while not path.exists() and time.monotonic() < deadline:  # the file exists once the recorder runs
            time.sleep(0.05)
        time.sleep(0.3)
        recorder.send_signal(signal.SIGINT)
        out, err = recorder.communicate(timeout=10)
    finally:
        _stop(recorder)
    assert recorder.returncode == 1, err  # the requested topic never appeared
    assert "recorded 0 message(s)" in out and "stopped: interrupted" in out
    assert "/never/published         0  [never appeared]" in out
    assert describe_mcap(path) == [] and list(read_mcap(path)) == []  # summary written: a valid, empty file


def test_play_loops_until_stopped(tmp_path, monkeypatch):
    monkeypatch.setenv("DPTPU_DISCOVERY_DIR", str(tmp_path / "graph"))
    path = tmp_path / "three.mcap"
    trigger = sample_messages()["/projector/trigger"]
    with McapRecordWriter(path) as writer:
        for index in range(3):
            writer.write("/projector/trigger", trigger, 1_000_000_000 + index * 40_000_000)  # 40 ms apart
    stop = threading.Event()
    threading.Timer(0.6, stop.set).start()
    started = time.monotonic()
    result = play(path, rate=4.0, loop=True, stop_event=stop)  # one pass: 2 gaps of 10 ms
    assert 0.55 < time.monotonic() - started < 2.0
    assert result.loops >= 3 and result.counts["/projector/trigger"] >= 3 * result.loops
    assert result.types == {"/projector/trigger": "dptpu_msgs/msg/Trigger"} and result.skipped == {}


# --------------------------------------------------------------------------------------------------
# QoS choices
# --------------------------------------------------------------------------------------------------

def test_recording_qos_matches_what_the_publishers_offer():
    reliable = QoSProfile(depth=10)
    best_effort = QoSProfile(depth=5, reliability=ReliabilityPolicy.BEST_EFFORT)
    latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    qos = recording_qos([reliable, reliable])
    assert (qos.history, qos.reliability, qos.durability) == (
        HistoryPolicy.KEEP_ALL, ReliabilityPolicy.RELIABLE, DurabilityPolicy.VOLATILE)
    assert recording_qos([reliable, best_effort]).reliability == ReliabilityPolicy.BEST_EFFORT
    assert recording_qos([latched]).durability == DurabilityPolicy.TRANSIENT_LOCAL
    assert recording_qos([latched, reliable]).durability == DurabilityPolicy.VOLATILE
    assert recording_qos([None]).reliability == ReliabilityPolicy.BEST_EFFORT  # unknown offer: connect to any


def test_playback_qos_is_reliable_and_keeps_recorded_durability():
    latched = playback_qos({"durability": "transient_local"})
    assert (latched.reliability, latched.durability, latched.depth) == (
        ReliabilityPolicy.RELIABLE, DurabilityPolicy.TRANSIENT_LOCAL, 1)
    plain = playback_qos(None)
    assert (plain.reliability, plain.durability, plain.depth) == (
        ReliabilityPolicy.RELIABLE, DurabilityPolicy.VOLATILE, PLAYBACK_DEPTH)


# --------------------------------------------------------------------------------------------------
# Errors
# --------------------------------------------------------------------------------------------------

def test_play_refuses_bad_arguments(tmp_path):
    path = tmp_path / "one.mcap"
    with McapRecordWriter(path) as writer:
        writer.write("/projector/trigger", sample_messages()["/projector/trigger"], 1)
    with pytest.raises(ValueError, match="rate must be a positive number; got 0"):
        play(path, rate=0)
    with pytest.raises(ValueError, match="has no topic.s. /nope; it has /projector/trigger"):
        play(path, topics=["/nope"])
    with pytest.raises(ValueError, match=r"delay_s must be a number of seconds >= 0; got -1"):
        play(path, delay_s=-1)


def test_cli_reports_bad_input_in_one_line(tmp_path, capsys):
    assert dptpu_main(["play", str(tmp_path / "missing.mcap")]) == 2
    assert "dptpu play: error: no MCAP file at" in capsys.readouterr().err
    assert dptpu_main(["record", "-o", str(tmp_path / "x.mcap"), "/t", "--duration", "-1"]) == 2
    assert "dptpu record: error: --duration must be > 0 seconds; got -1.0" in capsys.readouterr().err
    assert not (tmp_path / "x.mcap").exists()


def test_record_refuses_a_bad_topic_name_before_creating_the_file(tmp_path, monkeypatch):
    monkeypatch.setenv("DPTPU_DISCOVERY_DIR", str(tmp_path / "graph"))
    from dptpu.tools.recording.recorder import record

    with pytest.raises(ValueError, match="invalid topic name 'bad topic'"):
        record(tmp_path / "bad.mcap", ["bad topic"], duration_s=1.0)
    with pytest.raises(ValueError, match="max_messages must be a positive int; got 0"):
        record(tmp_path / "bad.mcap", ["/t"], max_messages=0)
    assert not (tmp_path / "bad.mcap").exists()
