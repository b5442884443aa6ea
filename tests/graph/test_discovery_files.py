"""Announcement files: stale ones (dead pid, reused pid, expired peer entry) are ignored and cleaned."""

from __future__ import annotations

import os
import subprocess
import sys
import time
import uuid

import pytest

from dptpu.graph.discovery import (
    FORMAT,
    DirectoryScanner,
    ensure_private_directory,
    get_graph,
    host_identity,
    process_start_ticks,
    resolve_domain_id,
    write_announcement,
)


def _entry(name: str, pid: int, pid_start, **extra) -> dict:
    host, boot_id = host_identity()
    entry = {"format": FORMAT, "name": name, "namespace": "/", "fqn": f"/{name}", "gid": uuid.uuid4().hex,
             "pid": pid, "pid_start": pid_start, "host": host, "boot_id": boot_id, "start_time": time.time(),
             "publishers": [], "subscriptions": [], "services": [], "clients": [], "service_endpoints": []}
    entry.update(extra)
    return entry


def _dead_pid() -> int:
    process = subprocess.Popen([sys.executable, "-c", "pass"])
    process.wait()
    return process.pid


def test_stale_announcements_are_ignored_then_deleted_with_their_socket_files(domain_dir):
    ensure_private_directory(domain_dir / "ep")
    me, my_start = os.getpid(), process_start_ticks(os.getpid())
    socket_file = domain_dir / "ep" / "deadbeef"
    socket_file.write_bytes(b"")
    files = {
        "alive": _entry("alive", me, my_start),
        "dead_pid": _entry("dead_pid", _dead_pid(), 1,
                           publishers=[{"topic": "/t", "type": "std_msgs/msg/String", "gid": "00",
                                        "endpoints": [f"ipc://{socket_file}"], "qos": {}}]),
        "reused_pid": _entry("reused_pid", me, my_start - 1),  # our pid, but a process that started earlier
        "expired_peer": _entry("expired_peer", me, my_start, via="peer", expires=time.time() - 1),
    }
    for name, entry in files.items():
        write_announcement(domain_dir, f"n-{entry['pid']}-{name}.json", entry)
    (domain_dir / "n-1-garbage.json").write_text("{not json")

    assert [n.name for n in get_graph(directory=domain_dir).nodes] == ["alive"]
    assert len(list(domain_dir.glob("n-*.json"))) == 5  # get_graph only reads

    host, boot_id = host_identity()
    scanner = DirectoryScanner(domain_dir, host=host, boot_id=boot_id)
    assert scanner.scan(now=0.0)
    assert [e["name"] for e in scanner.entries] == ["alive"]
    scanner.scan(now=10.0)  # the liveness pass deletes what is stale
    assert sorted(p.name for p in domain_dir.glob("n-*.json")) == ["n-1-garbage.json", f"n-{me}-alive.json"]
    assert not socket_file.exists()


def test_domain_id_comes_from_argument_then_environment():
    assert resolve_domain_id(5, env={"DPTPU_DOMAIN_ID": "9"}) == 5
    assert resolve_domain_id(None, env={"DPTPU_DOMAIN_ID": "9", "ROS_DOMAIN_ID": "3"}) == 9
    assert resolve_domain_id(None, env={"ROS_DOMAIN_ID": "3"}) == 3
    assert resolve_domain_id(None, env={}) == 0
    with pytest.raises(ValueError, match=r"\$ROS_DOMAIN_ID must be an integer in 0..232; got 'x'"):
        resolve_domain_id(None, env={"ROS_DOMAIN_ID": "x"})
    with pytest.raises(ValueError, match="domain_id must be an integer in 0..232; got 300"):
        resolve_domain_id(300)


def test_discovery_folder_is_made_private_and_one_others_may_write_is_refused(tmp_path):
    # ipc stays private to the user: the announcements name every endpoint, the socket files are inside
    readable = tmp_path / "readable"
    readable.mkdir(mode=0o755)
    os.chmod(readable, 0o755)
    assert (ensure_private_directory(readable).stat().st_mode & 0o777) == 0o700
    fresh = ensure_private_directory(tmp_path / "fresh" / "domain-0")
    assert (fresh.stat().st_mode & 0o777) == 0o700
    shared = tmp_path / "shared"
    shared.mkdir()
    os.chmod(shared, 0o777)
    with pytest.raises(PermissionError, match="writable by others"):
        ensure_private_directory(shared)


def test_a_rewrite_that_changes_only_counters_is_no_topology_change(domain_dir):
    ensure_private_directory(domain_dir)
    me, my_start = os.getpid(), process_start_ticks(os.getpid())
    publisher = {"topic": "/t", "type": "std_msgs/msg/String", "gid": "01", "endpoints": ["ipc:///x"], "qos": {},
                 "stats": {"published_count": 1}}
    entry = _entry("talker", me, my_start, publishers=[publisher], updated=1.0)
    name = f"n-{me}-talker.json"
    write_announcement(domain_dir, name, entry)
    host, boot_id = host_identity()
    scanner = DirectoryScanner(domain_dir, host=host, boot_id=boot_id)
    assert scanner.scan(now=0.0) and scanner.topology_changed  # a new node

    def rewrite(**changes) -> bool:
        nonlocal entry
        entry = {**entry, **changes}
        write_announcement(domain_dir, name, entry)
        os.utime(domain_dir / name, ns=(time.time_ns() + 10**9, time.time_ns() + 10**9))  # a new mtime for sure
        assert scanner.scan(now=0.1)
        return scanner.topology_changed

    # counters and the time written move: the snapshot is refreshed, the topology is the same
    assert not rewrite(publishers=[{**publisher, "stats": {"published_count": 50}}], updated=2.0)
    assert scanner.entries[0]["publishers"][0]["stats"] == {"published_count": 50}
    # an endpoint, a subscription or a process start time more is a change of topology
    assert rewrite(publishers=[{**publisher, "endpoints": ["ipc:///y"]}])
    assert rewrite(subscriptions=[{"topic": "/u", "type": "std_msgs/msg/String", "gid": "02", "qos": {}}])
    assert rewrite(pid_start=my_start - 1)  # not this process any more: asked again whether it is alive
    assert scanner.entries == []
