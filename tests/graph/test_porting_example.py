"""The talker/listener of docs/porting-to-ros2.md run unchanged on dptpu.graph (ROS 2 itself is not installed here)."""

from __future__ import annotations

import re
import signal
from pathlib import Path

DOC = Path(__file__).resolve().parents[2] / "docs" / "porting-to-ros2.md"
NODES = Path(__file__).parent / "nodes"


def test_doc_shows_the_tested_files_verbatim():
    text = DOC.read_text()
    for name in ("porting_talker.py", "porting_listener.py"):
        source = (NODES / name).read_text()
        body = source.split('"""', 2)[2].strip()  # the file without its docstring
        assert body in text, f"docs/porting-to-ros2.md does not show {name} as it is"


def test_talker_and_listener_run_on_dptpu_graph(spawn):
    listener = spawn("porting_listener", "--ros-args", "-p", "count:=3")
    talker = spawn("porting_talker", "--ros-args", "-p", "period_sec:=0.05")
    assert listener.wait(timeout=10) == 0
    heard = [int(n) for n in re.findall(r'\[minimal_subscriber\]: I heard: "Hello World: (\d+)"', listener.stderr)]
    assert len(heard) == 3 and heard == list(range(heard[0], heard[0] + 3))
    talker.proc.send_signal(signal.SIGINT)
    assert talker.wait(timeout=5) == 0
    assert re.search(r'^\[INFO\] \[\d+\.\d{9}\] \[minimal_publisher\]: Publishing: "Hello World: 0"$',
                     talker.stderr, re.MULTILINE)
