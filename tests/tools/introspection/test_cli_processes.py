"""The introspection CLI against a real talker process over real sockets.

One talker process (``talker_node.py``: a 4x8 mono8 Image ``level + [0..31]`` at 20 Hz on
``/talker/image``, parameters ``level``/``frame_id``/``rate_hz``, services ``~/reset`` and ``~/enable``)
runs for the whole module in a private discovery folder and domain :data:`DOMAIN_ID` (no other test
module uses it). Most commands run in-process through ``dptpu.cli.main.main`` (each builds and shuts
down its own context); two run as the real ``dptpu`` executable. Rates are measured values checked
within a wide band; no test asserts how long an operation takes.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import pytest

from dptpu.cli.main import main
from dptpu.messages import Header, Image, Time, encode

HERE = Path(__file__).parent
REPO_ROOT = HERE.parents[2]
#: This module's own domain (tests/graph uses 17).
DOMAIN_ID = 61
TOPIC = "/talker/image"
IMAGE_PIXELS = 32  # 4 x 8 mono8


@pytest.fixture(scope="module")
def graph_env():
    folder = tempfile.mkdtemp(prefix="dgi", dir="/tmp")
    values = {"DPTPU_DISCOVERY_DIR": folder, "DPTPU_DOMAIN_ID": str(DOMAIN_ID)}
    with pytest.MonkeyPatch.context() as patch:
        for name in ("ROS_DOMAIN_ID", "DPTPU_TRANSPORT", "DPTPU_TCP_INTERFACE", "DPTPU_CURVE_SECRET_KEY",
                     "DPTPU_CURVE_AUTHORIZED_KEYS", "DPTPU_PEERS", "DPTPU_DISCOVERY_PORT"):
            patch.delenv(name, raising=False)
        for name, value in values.items():
            patch.setenv(name, value)
        yield values
    shutil.rmtree(folder, ignore_errors=True)


def _child_env(graph_env) -> dict:
    env = dict(os.environ)
    env.update(graph_env)
    env["PYTHONPATH"] = str(REPO_ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    return env


@pytest.fixture(scope="module")
def talker(graph_env):
    """The talker process, killed at the end of the module whatever happens."""
    proc = subprocess.Popen([sys.executable, str(HERE / "talker_node.py"), "--lifetime", "60"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=_child_env(graph_env),
                            cwd=str(REPO_ROOT))
    ready: dict = {}
    got = threading.Event()

    def read():
        for line in proc.stdout:
            if line.startswith("{") and not ready:
                ready.update(json.loads(line))
                got.set()

    threading.Thread(target=read, daemon=True).start()
    try:
        assert got.wait(20.0), f"talker did not start; exit code {proc.poll()}; stderr:\n{proc.stderr.read()}"
        assert ready == {"event": "ready", "node": "/talker", "topic": TOPIC}
        yield proc
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.wait(timeout=5)


def cli(capsys, *argv) -> tuple[int, str, str]:
    """Run ``dptpu ARGV --domain-id 61`` in this process; return (exit code, stdout, stderr)."""
    capsys.readouterr()
    code = main([*argv, "--domain-id", str(DOMAIN_ID)])
    out, err = capsys.readouterr()
    return code, out, err


def echo_once(capsys) -> dict:
    code, out, err = cli(capsys, "topic", "echo", TOPIC, "--once", "--json", "--timeout", "5")
    assert code == 0, err
    lines = out.strip().splitlines()
    assert len(lines) == 1
    return json.loads(lines[0])


def test_node_list_with_the_real_executable_reads_the_domain_from_the_environment(talker, graph_env):
    result = subprocess.run([sys.executable, "-m", "dptpu.cli.main", "node", "list"], capture_output=True,
                            text=True, env=_child_env(graph_env), cwd=str(REPO_ROOT), timeout=30)
    assert (result.returncode, result.stdout) == (0, "/talker\n"), result.stderr
    other = dict(_child_env(graph_env), DPTPU_DOMAIN_ID=str(DOMAIN_ID + 1))
    result = subprocess.run([sys.executable, "-m", "dptpu.cli.main", "node", "list", "-c"], capture_output=True,
                            text=True, env=other, cwd=str(REPO_ROOT), timeout=30)
    assert (result.returncode, result.stdout) == (0, "0\n")  # another domain sees nothing


def test_topic_list_shows_the_topic_and_its_type(talker, capsys):
    assert cli(capsys, "topic", "list")[:2] == (0, f"{TOPIC}\n")
    assert cli(capsys, "topic", "list", "-t")[:2] == (0, f"{TOPIC} [sensor_msgs/msg/Image]\n")
    assert cli(capsys, "topic", "type", "talker/image")[:2] == (0, "sensor_msgs/msg/Image\n")


def test_node_info_lists_publisher_and_services(talker, capsys):
    code, out, _ = cli(capsys, "node", "info", "/talker")
    assert code == 0
    lines = out.splitlines()
    assert lines[0] == "/talker"
    publishers = lines.index("  Publishers:")
    assert lines[publishers + 1] == f"    {TOPIC}: sensor_msgs/msg/Image"
    assert "    /talker/reset: std_srvs/srv/Trigger" in lines
    assert "    /talker/get_parameters: rcl_interfaces/srv/GetParameters" in lines


def test_echo_once_json_gives_the_published_fields_with_the_array_summarized(talker, capsys):
    message = echo_once(capsys)
    assert message["header"]["frame_id"] == "talker_frame"
    assert abs(message["header"]["stamp"]["sec"] - time.time()) < 60
    assert (message["height"], message["width"], message["encoding"], message["step"]) == (4, 8, "mono8", 8)
    # level 7: pixels 7..38
    assert message["data"] == {"dtype": "uint8", "shape": [IMAGE_PIXELS], "min": 7, "max": 38, "mean": 22.5}


def test_echo_yaml_is_ros2_shaped_and_parses_back(talker, capsys):
    import yaml

    code, out, _ = cli(capsys, "topic", "echo", TOPIC, "--count", "2", "--timeout", "5")
    assert code == 0
    documents = [d for d in out.split("---\n") if d.strip()]
    assert len(documents) == 2
    first = yaml.safe_load(documents[0])
    assert first["encoding"] == "mono8"
    assert first["data"] == {"dtype": "uint8", "shape": [IMAGE_PIXELS], "min": 7, "max": 38, "mean": 22.5}
    assert "  frame_id: talker_frame" in documents[0].splitlines()


def test_topic_hz_measures_about_20_hz(talker, capsys):
    code, out, _ = cli(capsys, "topic", "hz", TOPIC, "--window", "20", "--timeout", "2.5")
    assert code == 0
    reports = re.findall(r"average rate: ([0-9.]+)\n\tmin: ([0-9.]+)s max: ([0-9.]+)s std dev: ([0-9.]+)s "
                         r"window: (\d+)", out)
    assert reports, out
    rate, low, high, std, window = (float(v) for v in reports[-1])
    assert 10.0 < rate < 30.0  # a 20 Hz timer, measured
    assert low - 5e-4 <= 1.0 / rate <= high + 5e-4  # printed to 3 decimals
    assert 0.0 <= std < high
    assert 2 <= window <= 20


def test_topic_bw_reports_the_serialized_size_of_the_image(talker, capsys):
    sample = Image.from_array(__import__("numpy").zeros((4, 8), "uint8"),
                              header=Header(stamp=Time.from_ns(time.time_ns()), frame_id="talker_frame"))
    size_bytes = sum(memoryview(frame).nbytes for frame in encode(TOPIC, sample))
    code, out, _ = cli(capsys, "topic", "bw", TOPIC, "--timeout", "1.5")
    assert code == 0
    lines = out.splitlines()
    assert lines[0] == f"Subscribed to [{TOPIC}]"
    match = re.search(r"([0-9.]+)(B|KB|MB)/s from (\d+) messages\n\tMessage size mean: ([0-9.]+)\2 "
                      r"min: ([0-9.]+)\2 max: ([0-9.]+)\2", out)
    assert match, out
    scale = {"B": 1.0, "KB": 1e3, "MB": 1e6}[match.group(2)]
    for group in (4, 5, 6):  # every message has the same size: topic + msgpack header + 32 pixel bytes
        assert float(match.group(group)) * scale == pytest.approx(size_bytes, abs=0.005 * scale + 2)
    assert 10 * size_bytes < float(match.group(1)) * scale < 30 * size_bytes  # ~20 messages per second


def test_param_get_set_dump_round_trip_changes_what_the_node_publishes(talker, capsys):
    assert cli(capsys, "param", "get", "/talker", "level")[:2] == (0, "Integer value is: 7\n")
    assert cli(capsys, "param", "get", "/talker", "rate_hz", "--hide-type")[:2] == (0, "20.0\n")
    code, out, _ = cli(capsys, "param", "list", "/talker")
    assert (code, out.split()) == (0, ["frame_id", "level", "rate_hz", "use_sim_time"])
    try:
        assert cli(capsys, "param", "set", "/talker", "level", "42")[:2] == (0, "Set parameter successful\n")
        assert cli(capsys, "param", "set", "/talker", "frame_id", "camera_frame")[0] == 0
        assert cli(capsys, "param", "get", "/talker", "level")[1] == "Integer value is: 42\n"
        deadline = time.monotonic() + 5.0
        message = echo_once(capsys)
        while message["data"]["min"] != 42 and time.monotonic() < deadline:  # one image may be in flight
            message = echo_once(capsys)
        assert message["data"] == {"dtype": "uint8", "shape": [IMAGE_PIXELS], "min": 42, "max": 73, "mean": 57.5}
        assert message["header"]["frame_id"] == "camera_frame"
        code, out, _ = cli(capsys, "param", "dump", "/talker")
        assert code == 0
        assert out == ("/talker:\n  ros__parameters:\n    frame_id: camera_frame\n    level: 42\n"
                       "    rate_hz: 20.0\n    use_sim_time: false\n")
    finally:
        main(["param", "set", "/talker", "level", "7", "--domain-id", str(DOMAIN_ID)])
        main(["param", "set", "/talker", "frame_id", "talker_frame", "--domain-id", str(DOMAIN_ID)])


def test_param_set_refused_by_the_node_exits_1_with_its_reason(talker, capsys):
    code, out, _ = cli(capsys, "param", "set", "/talker", "rate_hz", "-1.0")
    assert (code, out) == (1, "Setting parameter failed: rate_hz must be > 0\n")
    code, out, _ = cli(capsys, "param", "set", "/talker", "level", "4.5")  # YAML 4.5 is a DOUBLE
    assert code == 1 and "is of type INTEGER, setting it to DOUBLE" in out
    assert cli(capsys, "param", "get", "/talker", "level")[1] == "Integer value is: 7\n"


def test_service_call_trigger_and_setbool(talker, capsys):
    code, out, _ = cli(capsys, "service", "call", "/talker/reset", "std_srvs/srv/Trigger")
    assert code == 0
    assert out.startswith("requester: making request: std_srvs.srv.Trigger_Request()\n\nresponse:\n")
    published = int(re.search(r"Trigger_Response\(success=True, message='published (\d+) images'\)", out).group(1))
    assert published >= 1
    code, out, _ = cli(capsys, "service", "call", "--json", "/talker/enable", "std_srvs/SetBool", "{data: false}")
    assert (code, json.loads(out)) == (0, {"success": True, "message": "paused"})
    try:
        main(["service", "call", "/talker/reset", "std_srvs/srv/Trigger", "--domain-id", str(DOMAIN_ID)])
        code, _, err = cli(capsys, "topic", "echo", TOPIC, "--once", "--timeout", "0.6")
        assert code == 1 and f"no message on {TOPIC} within 0.6 s" in err
        code, out, _ = cli(capsys, "service", "call", "--json", "/talker/reset", "std_srvs/srv/Trigger")
        assert (code, json.loads(out)) == (0, {"success": True, "message": "published 0 images"})
    finally:
        code, out, _ = cli(capsys, "service", "call", "--json", "/talker/enable", "std_srvs/SetBool", "{data: true}")
    assert (code, json.loads(out)) == (0, {"success": True, "message": "publishing"})
    assert echo_once(capsys)["data"]["min"] == 7


def test_service_list_shows_served_services_with_types(talker, capsys):
    code, out, _ = cli(capsys, "service", "list", "-t")
    assert code == 0
    lines = out.splitlines()
    assert lines == sorted(lines) and len(lines) == 8  # 6 parameter services + reset + enable
    assert "/talker/reset [std_srvs/srv/Trigger]" in lines
    assert "/talker/enable [std_srvs/srv/SetBool]" in lines


@pytest.mark.parametrize("argv, message", [
    (["topic", "echo", "/nope"], "topic /nope is not in the graph of domain 61; known topics with a publisher: "
                                 "/talker/image"),
    (["topic", "hz", "/nope"], "topic /nope is not in the graph of domain 61"),
    (["node", "info", "/nope"], "node /nope is not in the graph of domain 61; known nodes: /talker"),
    (["param", "get", "/nope", "level"], "node /nope is not in the graph of domain 61"),
    (["param", "get", "/talker", "nope"], "node /talker has no parameter 'nope'; its parameters: frame_id, level, "
                                          "rate_hz, use_sim_time"),
    (["service", "call", "/nope", "std_srvs/srv/Trigger"], "service /nope is not served in domain 61"),
    (["service", "call", "/talker/reset", "std_srvs/srv/SetBool"],
     "service /talker/reset has type std_srvs/srv/Trigger; got std_srvs/srv/SetBool"),
    (["service", "call", "/talker/enable", "std_srvs/srv/SetBool", "{dat: true}"],
     "SetBool.Request has no field(s) dat; its fields: data"),
    (["service", "call", "/talker/enable", "no_pkg/srv/Nothing"], "unknown service type 'no_pkg/srv/Nothing'"),
    (["param", "set", "/talker", "level", "{a: 1}"], "must be a scalar or a list, not a mapping"),
])
def test_unknown_names_and_bad_input_exit_2_with_a_clear_message(talker, capsys, argv, message):
    code, out, err = cli(capsys, *argv, "--spin-time", "0.1")
    assert (code, out) == (2, "")
    assert message in err


def test_unknown_topic_with_the_real_executable_exits_2(talker, graph_env):
    result = subprocess.run([sys.executable, "-m", "dptpu.cli.main", "topic", "bw", "/nope", "--spin-time", "0"],
                            capture_output=True, text=True, env=_child_env(graph_env), cwd=str(REPO_ROOT), timeout=30)
    assert result.returncode == 2
    assert result.stderr.strip() == ("dptpu topic: error: topic /nope is not in the graph of domain 61; known topics "
                                     "with a publisher: /talker/image")
