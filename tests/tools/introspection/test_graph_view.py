"""Graph listing and lookups on announcement files written by hand (no processes)."""

from __future__ import annotations

import os

import pytest

from dptpu.graph.discovery import FORMAT, host_identity, process_start_ticks, snapshot_from_entries, write_announcement
from dptpu.tools.introspection import (
    UnknownNameError,
    find_node,
    find_service,
    find_topic,
    format_node_info,
    format_topic_info,
    is_hidden_node,
    node_names,
    read_graph,
)

DOMAIN_ID = 63
QOS = {"history": "keep_last", "depth": 5, "reliability": "best_effort", "durability": "volatile"}


def _entry(name: str, namespace: str = "/", *, publishers=(), subscriptions=(), services=()) -> dict:
    host, boot_id = host_identity()
    fqn = (namespace.rstrip("/") + "/" + name)
    return {"format": FORMAT, "name": name, "namespace": namespace, "fqn": fqn, "gid": f"g{name}",
            "pid": os.getpid(), "pid_start": process_start_ticks(os.getpid()), "host": host, "boot_id": boot_id,
            "start_time": 0.0,
            "publishers": [{"topic": t, "type": ty, "gid": f"p{t}", "endpoints": [], "qos": QOS,
                            "stats": {"published_count": 9}} for t, ty in publishers],
            "subscriptions": [{"topic": t, "type": ty, "gid": f"s{t}", "qos": QOS,
                               "stats": {"received_count": 8, "dropped_count": 1}} for t, ty in subscriptions],
            "services": [{"name": s, "type": ty} for s, ty in services], "clients": []}


@pytest.fixture
def graph(monkeypatch, tmp_path):
    monkeypatch.setenv("DPTPU_DISCOVERY_DIR", str(tmp_path))
    folder = tmp_path / f"domain-{DOMAIN_ID}"
    folder.mkdir(mode=0o700)
    entries = [
        _entry("phase", "/scanner", publishers=[("/scanner/phase", "dptpu_msgs/msg/PhaseMaps")],
               subscriptions=[("/camera/image_raw", "sensor_msgs/msg/Image")],
               services=[("/scanner/phase/get_parameters", "rcl_interfaces/srv/GetParameters")]),
        _entry("camera", publishers=[("/camera/image_raw", "sensor_msgs/msg/Image")]),
        _entry("_dptpu_cli_1", subscriptions=[("/scanner/phase", "dptpu_msgs/msg/PhaseMaps")]),
    ]
    for index, entry in enumerate(entries):
        write_announcement(folder, f"n-{os.getpid()}-{index}.json", entry)
    return entries


def test_hidden_nodes_and_their_endpoints_are_left_out_unless_asked(graph):
    visible = read_graph(DOMAIN_ID)
    assert node_names(visible) == ["/camera", "/scanner/phase"]
    assert visible.topics["/scanner/phase"].subscription_count == 0
    everything = read_graph(DOMAIN_ID, include_hidden=True)
    assert node_names(everything) == ["/_dptpu_cli_1", "/camera", "/scanner/phase"]
    assert everything.topics["/scanner/phase"].subscription_count == 1
    assert is_hidden_node("/_dptpu_cli_1") and not is_hidden_node("/_ns/camera")


def test_lookups_find_names_and_raise_unknown_name_error_listing_what_exists(graph):
    assert find_node("scanner/phase", DOMAIN_ID).pid == os.getpid()
    assert find_topic("/camera/image_raw", DOMAIN_ID).types == ("sensor_msgs/msg/Image",)
    assert find_service("/scanner/phase/get_parameters", DOMAIN_ID).servers == ("/scanner/phase",)
    with pytest.raises(UnknownNameError, match="node /phase is not in the graph of domain 63; known nodes: /camera, "
                                               "/scanner/phase"):
        find_node("/phase", DOMAIN_ID)
    with pytest.raises(ValueError, match="topic /nope is not in the graph of domain 63; known topics with a "
                                         "publisher: /camera/image_raw, /scanner/phase"):
        find_topic("/nope", DOMAIN_ID)
    with pytest.raises(UnknownNameError, match="service /x is not served in domain 63"):
        find_service("/x", DOMAIN_ID)


def test_a_topic_with_only_subscriptions_has_no_publisher(monkeypatch, tmp_path):
    monkeypatch.setenv("DPTPU_DISCOVERY_DIR", str(tmp_path))
    folder = tmp_path / f"domain-{DOMAIN_ID}"
    folder.mkdir(mode=0o700)
    write_announcement(folder, f"n-{os.getpid()}-0.json",
                       _entry("listener", subscriptions=[("/chatter", "std_msgs/msg/String")]))
    with pytest.raises(UnknownNameError, match="topic /chatter has no publisher of domain 63; there are no topics "
                                               "with a publisher"):
        find_topic("/chatter", DOMAIN_ID)
    assert find_topic("/chatter", DOMAIN_ID, need_publisher=False).subscription_count == 1


def test_dead_processes_are_not_listed(monkeypatch, tmp_path):
    monkeypatch.setenv("DPTPU_DISCOVERY_DIR", str(tmp_path))
    folder = tmp_path / f"domain-{DOMAIN_ID}"
    folder.mkdir(mode=0o700)
    entry = _entry("ghost")
    entry["pid"] = 2**22 + 12345  # above the kernel's pid_max: no such process
    write_announcement(folder, "n-1-0.json", entry)
    assert node_names(read_graph(DOMAIN_ID)) == []


def test_node_info_and_topic_info_text(graph):
    snapshot = snapshot_from_entries(graph, DOMAIN_ID)
    phase = next(n for n in snapshot.nodes if n.name == "phase")
    assert format_node_info(phase).splitlines() == [
        "/scanner/phase", "  Subscribers:", "    /camera/image_raw: sensor_msgs/msg/Image", "  Publishers:",
        "    /scanner/phase: dptpu_msgs/msg/PhaseMaps", "  Service Servers:",
        "    /scanner/phase/get_parameters: rcl_interfaces/srv/GetParameters", "  Service Clients:"]
    image = snapshot.topics["/camera/image_raw"]
    assert format_topic_info(image) == "Type: sensor_msgs/msg/Image\n\nPublisher count: 1\nSubscription count: 1"
    verbose = format_topic_info(image, verbose=True).splitlines()
    assert "Node name: phase" in verbose and "Node namespace: /scanner" in verbose
    assert "    Reliability: BEST_EFFORT" in verbose and "    History (Depth): KEEP_LAST (5)" in verbose
    assert "    dropped_count: 1" in verbose and "    published_count: 9" in verbose
