"""``dptpu launch`` with real processes: output prefixes, argv, respawn, shutdown without orphans, required nodes.

Each test runs the launcher as a subprocess (its own session, so a finally block can always kill it
and everything it reported starting) with the repository on PYTHONPATH, and the fixture programs of
``tests/tools/launch/fixtures`` as nodes.
"""
from __future__ import annotations

import io
import json
import os
import re
import signal
import time

from dptpu.tools.launch import Supervisor, load_launch_file
from tests.tools.launch.conftest import (
    FIXTURES,
    REPO_ROOT,
    LaunchProcess,
    launcher_env,
    process_running,
)


def _all_gone(pids, timeout_s=1.0) -> list[int]:
    """Pids still running after ``timeout_s`` (normally none)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline and any(map(process_running, pids)):
        time.sleep(0.02)
    return [pid for pid in pids if process_running(pid)]


def test_three_nodes_run_with_prefixed_output_and_stop_on_sigint(write_file):
    path = write_file("three.yaml", f"""
        launch:
          - node: {{pkg: {FIXTURES}, exec: ticker, name: alpha}}
          - node: {{pkg: {FIXTURES}, exec: ticker, name: beta}}
          - node: {{pkg: {FIXTURES}, exec: ticker, name: gamma}}
        """)
    launch = LaunchProcess(path, env=launcher_env(DPTPU_DOMAIN_ID="42"))
    try:
        pids = {label: int(launch.wait_for(rf"^\[{label}\] pid=(\d+) .* domain=42$").group(1))
                for label in ("alpha", "beta", "gamma")}
        for label in pids:
            launch.wait_for(rf"^\[{label}\] tick 2$")
        launch.wait_for(r"^\[alpha\] to stderr$")  # stderr is prefixed too
        assert sorted(pids.values()) == sorted(launch.pids())
        assert len(set(pids.values())) == 3 and os.getpid() not in pids.values()
        # each node leads its own process group
        assert all(os.getpgid(pid) == pid for pid in pids.values())
        started = time.monotonic()
        launch.process.send_signal(signal.SIGINT)
        assert launch.finish(timeout_s=5.0) == 0
        assert time.monotonic() - started < 5.0
        for label in pids:
            assert any(line == f"[{label}] stopping on SIGINT" for line in launch.lines)
        node_lines = [line for line in launch.lines if not line.startswith("[launch]")]
        assert node_lines and all(re.match(r"^\[(alpha|beta|gamma)\] ", line) for line in node_lines)
        assert _all_gone(list(pids.values())) == []
    finally:
        launch.kill_everything()


def test_remaps_and_params_reach_the_child_argv_exactly(write_file):
    params = write_file("params.yaml", "/**:\n  ros__parameters:\n    gain: 2\n")
    path = write_file("argv.yaml", f"""
        launch:
          - arg: {{name: rate, default: "10"}}
          - node:
              pkg: {FIXTURES}
              exec: ticker
              name: cam
              namespace: scanner
              args: --verbose
              param:
                - {{name: min_modulation, value: 5.0}}
                - {{name: rate, value: $(var rate)}}
                - {{from: params.yaml}}
                - {{name: topics, value: [a, b]}}
              remap:
                - {{from: /camera/image_raw, to: /sim/image}}
                - {{from: points, to: /out/points}}
        """)
    launch = LaunchProcess(path, "rate:=25")
    try:
        argv = json.loads(launch.wait_for(r"^\[cam\] pid=\d+ argv=(.*) domain=").group(1))
        assert argv == ["--verbose", "--ros-args", "-r", "__node:=cam", "-r", "__ns:=/scanner",
                        "-p", "min_modulation:=5.0", "-p", "rate:=25", "--params-file", str(params),
                        "-p", 'topics:=["a", "b"]',
                        "-r", "/camera/image_raw:=/sim/image", "-r", "points:=/out/points"]
        launch.process.send_signal(signal.SIGTERM)
        assert launch.finish(timeout_s=5.0) == 0
    finally:
        launch.kill_everything()


def test_killed_node_is_respawned_with_a_new_pid(write_file):
    path = write_file("respawn.yaml", f"""
        launch:
          - node: {{pkg: {FIXTURES}, exec: ticker, name: worker, respawn: true, respawn_delay: 0.3}}
        """)
    launch = LaunchProcess(path)
    new_pid = None
    try:
        first_pid = int(launch.wait_for(r"^\[worker\] pid=(\d+) ").group(1))
        killed_at = time.monotonic()
        os.kill(first_pid, signal.SIGKILL)
        launch.wait_for(rf"^\[launch\] 'worker' \(pid {first_pid}\) was killed by SIGKILL; respawning in 0\.30 s")
        new_pid = int(launch.wait_for(rf"^\[worker\] pid=(?!{first_pid} )(\d+) ").group(1))
        assert time.monotonic() - killed_at >= 0.3
        assert new_pid != first_pid and process_running(new_pid)
        assert not process_running(first_pid)
        launch.wait_for(r"^\[worker\] tick 1$")
        launch.process.send_signal(signal.SIGINT)
        assert launch.finish(timeout_s=5.0) == 0
        assert _all_gone([new_pid]) == []
    finally:
        launch.kill_everything((new_pid,) if new_pid else ())


def test_sigint_stops_stubborn_nodes_and_their_helpers_within_5_s(write_file):
    path = write_file("stubborn.yaml", f"""
        launch:
          - node: {{pkg: {FIXTURES}, exec: ticker, name: ticker}}
          - node: {{pkg: {FIXTURES}, exec: stubborn, name: stubborn}}
        """)
    launch = LaunchProcess(path)
    pids: list[int] = []
    try:
        pids.append(int(launch.wait_for(r"^\[ticker\] pid=(\d+) ").group(1)))
        match = launch.wait_for(r"^\[stubborn\] pid=(\d+) helper=(\d+)$")
        pids += [int(match.group(1)), int(match.group(2))]
        assert all(map(process_running, pids))
        assert os.getpgid(pids[2]) == pids[1]  # the helper is in the stubborn node's group
        started = time.monotonic()
        launch.process.send_signal(signal.SIGINT)
        code = launch.finish(timeout_s=6.0)
        elapsed_s = time.monotonic() - started
        assert code == 0
        assert elapsed_s < 5.0
        assert _all_gone(pids, timeout_s=0.5) == []  # no orphan: node, helper, ticker all gone
        assert "[launch] sending SIGKILL to 'stubborn'" in launch.lines  # SIGINT, SIGTERM were ignored
    finally:
        launch.kill_everything(tuple(pids))


def test_required_node_failure_stops_everything_and_exits_non_zero(write_file):
    path = write_file("required.yaml", f"""
        launch:
          - node: {{pkg: {FIXTURES}, exec: ticker, name: bystander}}
          - node: {{pkg: {FIXTURES}, exec: crasher, name: essential, on_exit: shutdown}}
        """)
    launch = LaunchProcess(path)
    bystander = None
    try:
        bystander = int(launch.wait_for(r"^\[bystander\] pid=(\d+) ").group(1))
        assert launch.finish(timeout_s=6.0) == 1
        assert any(line.startswith("[launch] required node 'essential' (pid ") and
                   line.endswith("exited with code 3: stopping everything") for line in launch.lines)
        assert "[bystander] stopping on SIGINT" in launch.lines
        assert _all_gone([bystander]) == []
    finally:
        launch.kill_everything((bystander,) if bystander else ())


# --------------------------------------------------------------------------------------------------
# in-process supervisor (no launcher start-up): exit codes and log files
# --------------------------------------------------------------------------------------------------

def _supervise(path, **options):
    plan = load_launch_file(path, cwd=REPO_ROOT)
    stdout, stderr = io.StringIO(), io.StringIO()
    code = Supervisor(plan.nodes, stdout=stdout, stderr=stderr, env=launcher_env(), cwd=REPO_ROOT,
                      **options).run(handle_signals=False)
    return code, stdout.getvalue(), stderr.getvalue()


def test_launch_ends_with_0_when_every_node_has_exited_and_required_success_is_not_failure(write_file):
    path = write_file("exits.yaml", f"""
        launch:
          - node: {{pkg: {FIXTURES}, exec: crasher, name: flaky}}
          - node: {{exec: sh, name: quick, args: [-c, "echo done; exit 0"], on_exit: shutdown}}
        """)
    code, stdout, stderr = _supervise(path)
    assert code == 0
    assert "[quick] done\n" in stdout
    assert "[launch] required node 'quick'" in stderr and "exited with code 0: stopping everything" in stderr


def test_output_log_goes_to_a_file_not_the_screen(write_file, tmp_path):
    path = write_file("logged.yaml", """
        launch:
          - node: {exec: sh, name: quiet, args: [-c, "echo to-log"], output: log}
          - node: {exec: sh, name: loud, args: [-c, "echo to-both"], output: both}
        """)
    code, stdout, stderr = _supervise(path, log_dir=tmp_path / "logs")
    assert code == 0
    assert "to-log" not in stdout and "[loud] to-both\n" in stdout
    assert (tmp_path / "logs" / "quiet.log").read_text() == "to-log\n"
    assert (tmp_path / "logs" / "loud.log").read_text() == "to-both\n"


def test_a_node_with_a_configuration_error_is_not_respawned_and_stops_the_launch(write_file):
    # the real sim node, given an integer for its DOUBLE parameter frame_rate_hz: it exits 2 with one line
    path = write_file("misconfigured.yaml", f"""
        launch:
          - node: {{pkg: {FIXTURES}, exec: ticker, name: bystander}}
          - node: {{pkg: dptpu, exec: sim, respawn: true, respawn_delay: 0.1,
                    param: [{{name: frame_rate_hz, value: 2}}]}}
        """)
    launch = LaunchProcess(path)
    try:
        assert launch.finish(timeout_s=60.0) == 2
        (line,) = [line for line in launch.lines if "a configuration error" in line]
        assert re.fullmatch(r"\[launch\] 'sim' \(pid \d+\) exited with code 2, a configuration error: sim: error: "
                            r"wrong type for parameter 'frame_rate_hz': .* setting it to INTEGER is not allowed .*; "
                            r"not respawned: stopping everything", line), line
        assert not [line for line in launch.lines if "respawning" in line]
        assert "[bystander] stopping on SIGINT" in launch.lines
    finally:
        launch.kill_everything()
