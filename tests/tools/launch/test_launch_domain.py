"""Two graphs side by side (issue 16/18, outside tester): two graphs started in one domain mixed silently (a second
scan monitor reported the other graph's scans as its own). ``dptpu launch --domain-id N`` runs a graph in its own
domain, and the refusal of a second node of one name says to do so."""
from __future__ import annotations

import signal
import subprocess
import sys

from dptpu.graph.known_publishers import KnownPublishers, select_publishers
from tests.tools.launch.conftest import FIXTURES, REPO_ROOT, LaunchProcess, launcher_env

TICKERS = f"""
launch:
  - node: {{pkg: {FIXTURES}, exec: ticker, name: alpha}}
  - node: {{pkg: {FIXTURES}, exec: ticker, name: beta}}
"""


def test_domain_id_puts_every_node_of_the_launch_in_that_domain(write_file):
    path = write_file("tickers.yaml", TICKERS)
    launch = LaunchProcess(path, "--domain-id", "7", env=launcher_env(DPTPU_DOMAIN_ID="42"))  # the option wins
    try:
        for label in ("alpha", "beta"):
            launch.wait_for(rf"^\[{label}\] pid=\d+ .* domain=7$")
        launch.process.send_signal(signal.SIGINT)
        assert launch.finish(timeout_s=10.0) == 0
    finally:
        launch.kill_everything()


def test_a_domain_outside_0_to_232_is_refused_in_one_line(write_file):
    path = write_file("tickers.yaml", TICKERS)
    result = subprocess.run([sys.executable, "-m", "dptpu.cli.main", "launch", str(path), "--domain-id", "233"],
                            cwd=REPO_ROOT, env=launcher_env(), capture_output=True, text=True, timeout=60)
    assert result.returncode == 2
    assert result.stderr == "dptpu launch: error: --domain-id must be an integer in 0..232; got 233\n"
    assert "started" not in result.stdout + result.stderr  # nothing ran


def test_a_second_node_of_one_name_is_refused_with_what_to_do():
    # the older /cloud (pid 10) is the first graph's; the second graph's monitor refuses its own graph's /cloud
    first = ({"fqn": "/cloud", "pid": 10, "start_time": 100.0, "gid": "a"}, {"topic": "/scanner/status", "gid": "p1"})
    second = ({"fqn": "/cloud", "pid": 20, "start_time": 200.0, "gid": "b"}, {"topic": "/scanner/status", "gid": "p2"})
    accepted, refused = select_publishers([second, first], KnownPublishers(nodes=("/cloud",)))
    assert accepted == [first]
    (reason,) = [r[2] for r in refused]
    assert reason.startswith("a second node named /cloud (pid 20); the one of pid 10 is older. Two graphs in one "
                             "domain? Run each in its own domain (DPTPU_DOMAIN_ID=N in its environment, or dptpu "
                             "launch --domain-id N)"), reason
