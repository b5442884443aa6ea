"""``dptpu launch`` argument handling: --print, --show-args, and invalid files exiting 2 before anything runs."""
from __future__ import annotations

import contextlib
import io
import os
import shlex
import sys

from dptpu.cli.main import main
from tests.tools.launch.conftest import FIXTURES, REPO_ROOT, TICKER


def _run(*argv):
    stdout, stderr = io.StringIO(), io.StringIO()
    cwd = os.getcwd()
    os.chdir(REPO_ROOT)
    try:
        with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
            code = main(["launch", *argv])
    finally:
        os.chdir(cwd)
    return code, stdout.getvalue(), stderr.getvalue()


def test_print_shows_resolved_command_lines_with_options_after_the_file(write_file):
    path = write_file("rig.yaml", f"""
        launch:
          - arg: {{name: ns, default: /left}}
          - node: {{pkg: {FIXTURES}, exec: ticker, name: cam, namespace: $(var ns), respawn: true, respawn_delay: 0.5}}
        """)
    code, stdout, _ = _run(str(path), "ns:=/right", "--print")
    assert code == 0
    assert f"[cam]  # {path}:3; respawn (delay 0.5 s, max 30 s), output: screen" in stdout
    expected = [sys.executable, "-m", TICKER, "--ros-args", "-r", "__node:=cam", "-r", "__ns:=/right"]
    assert shlex.join(expected) in stdout.splitlines()
    assert "#   ns:=/right" in stdout


def test_show_args_lists_names_descriptions_and_defaults(write_file):
    path = write_file("rig.yaml", """
        launch:
          - arg: {name: rate, default: "10", description: frames per second}
          - arg: {name: mode}
        """)
    code, stdout, _ = _run("--show-args", str(path))
    assert code == 0
    assert "'rate':\n        frames per second\n        (default: '10')" in stdout
    assert "'mode':\n        no description given\n        (default: (no default: required))" in stdout


def test_invalid_file_exits_2_with_file_and_line(write_file):
    path = write_file("rig.yaml", f"launch:\n  - node: {{pkg: {FIXTURES}, exec: ticker, remapp: []}}\n")
    code, stdout, stderr = _run(str(path))
    assert code == 2
    assert stderr == f"dptpu launch: error: {path}:2: node: unknown key 'remapp' (did you mean 'remap'?)\n"
    assert stdout == ""


def test_a_file_in_the_old_dialect_lists_each_old_key_with_its_ros2_spelling_one_per_line(write_file):
    path = write_file("old.yaml", f"""
        launch:
          - arg: {{name: mode, default: a, choices: [a, b]}}
          - node: {{module: {TICKER}, required: true}}
        """)
    code, stdout, stderr = _run(str(path))
    assert code == 2 and stdout == ""
    assert stderr.splitlines() == [
        "dptpu launch: error: 2 problems in the launch file:",
        f"  {path}:2: arg: 'choices' is the old spelling; ROS 2 launch YAML writes 'choice', a list of {{value: ...}} "
        f"(choice: [{{value: a}}, {{value: b}}])",
        f"  {path}:3: node: 'module' is the old spelling; ROS 2 launch YAML writes 'pkg' and 'exec' (pkg: dptpu, "
        f"exec: NODE runs dptpu.nodes.NODE)"]


def test_malformed_launch_argument_exits_2(write_file):
    path = write_file("rig.yaml", "launch:\n  - arg: {name: rate, default: '1'}\n")
    code, _, stderr = _run(str(path), "rate=5")
    assert code == 2
    assert "launch arguments are written NAME:=VALUE (e.g. rate:=10); got 'rate=5'" in stderr
