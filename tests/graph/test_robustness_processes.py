"""A node survives its own callback's exception and malformed input; both are logged and counted."""

from __future__ import annotations

import os
import time
import uuid

import zmq

from dptpu.graph.discovery import (
    FORMAT,
    get_graph,
    host_identity,
    process_start_ticks,
    write_announcement,
)
from dptpu.graph.interfaces import String
from dptpu.graph.qos import QoSProfile
from dptpu.graph.transport import pack_envelope
from dptpu.messages import encode


def test_exception_in_callback_is_logged_with_node_and_topic_and_node_keeps_running(spawn):
    listener = spawn("listener", "--count", "3", "--raise-on", "1")
    listener.wait_event("ready")
    talker = spawn("talker", "--count", "3", "--wait-subs", "1")
    talker.wait_event("published")
    done = listener.wait_event("done")
    assert done["received"] == ["0", "1", "2"]  # the message after the failing one still arrives
    assert done["exception_count"] == 1
    assert listener.wait() == 0
    assert "exception in subscription callback on topic /chatter of node /listener" in listener.stderr
    assert "ZeroDivisionError: test callback failure on '1'" in listener.stderr
    assert "[ERROR]" in listener.stderr


def _announce_raw_publisher(domain_dir, endpoint: str, topic: str) -> str:
    """Announce a hand-made publisher the way any participant does: one JSON file."""
    host, boot_id = host_identity()
    gid = uuid.uuid4().hex
    entry = {"format": FORMAT, "name": "raw_injector", "namespace": "/", "fqn": "/raw_injector", "gid": gid,
             "pid": os.getpid(), "pid_start": process_start_ticks(os.getpid()), "host": host, "boot_id": boot_id,
             "start_time": time.time(), "service_endpoints": [], "curve_public_key": None,
             "publishers": [{"topic": topic, "type": String.TYPE_NAME, "gid": uuid.uuid4().hex,
                             "endpoints": [endpoint], "qos": QoSProfile(depth=10).to_dict()}],
             "subscriptions": [], "services": [], "clients": []}
    name = f"n-{os.getpid()}-{gid}.json"
    write_announcement(domain_dir, name, entry)
    return name


def test_malformed_messages_are_counted_and_visible_in_introspection(spawn, domain_dir):
    listener = spawn("listener", "--count", "1", "--linger", "2.5")
    listener.wait_event("ready")
    context = zmq.Context()
    sock = context.socket(zmq.XPUB)
    endpoint = f"ipc://{domain_dir}/ep/rawinjector"
    try:
        sock.bind(endpoint)
        name = _announce_raw_publisher(domain_dir, endpoint, "/chatter")
        assert sock.poll(5000), "the listener never subscribed to the announced raw publisher"
        events = [sock.recv()]
        while sock.poll(500):  # the topic, and the shared-memory descriptors' topic of this host (graph/shared_memory)
            events.append(sock.recv())
        assert b"\x01/chatter" in events
        gid = uuid.uuid4().bytes
        sock.send_multipart([b"/chatter", b"\x00garbage"])                                 # too few frames
        sock.send_multipart([b"/chatter", b"\xc1 not msgpack", pack_envelope(0, 2, 0, gid)])  # DecodeError
        sock.send_multipart(encode("/chatter", String(data="x")) + [b"short envelope"])    # bad envelope
        sock.send_multipart(encode("/chatter", String(data="good")) + [pack_envelope(0, 3, 0, gid)])
        done = listener.wait_event("done")
        assert done["received"] == ["good"]
        assert done["malformed_count"] == 3
        # stderr is read by its own thread: the warning may land a moment after the "done" event on stdout
        assert listener.wait_for_stderr("malformed message on /chatter"), listener.stderr
        # the counters reach the announcement within about a second
        deadline = time.monotonic() + 2.0
        stats = {}
        while time.monotonic() < deadline:
            subscriptions = [s for n in get_graph(directory=domain_dir).nodes if n.fully_qualified_name == "/listener"
                             for s in n.subscriptions]
            stats = subscriptions[0].stats if subscriptions else {}
            if stats.get("malformed_count") == 3:
                break
            time.sleep(0.1)
        assert stats.get("malformed_count") == 3
        assert stats.get("taken_count") == 1
        os.unlink(domain_dir / name)
    finally:
        sock.close(linger=0)
        context.term()
