"""Garbage on a node's service socket (issue 19, tried as an outside tester on a running rig): each malformed request
is counted and logged, an undecodable one answered with an error, and the next real request answered as usual."""
from __future__ import annotations

import json
import os
import socket
import time
import uuid

import zmq

from dptpu.graph import Trigger
from dptpu.graph.transport import FLAG_ERROR, FLAG_REQUEST, FLAG_RESPONSE, pack_envelope, unpack_envelope
from dptpu.messages import decode, encode


def _service_endpoint(domain_dir, fqn: str) -> str:
    deadline = time.monotonic() + 10  # the announcement is written by the node's I/O thread, after "ready"
    while time.monotonic() < deadline:
        for path in domain_dir.glob("n-*.json"):
            entry = json.loads(path.read_text())
            if entry.get("fqn") == fqn and entry.get("service_endpoints"):
                return entry["service_endpoints"][0]
        time.sleep(0.1)
    raise AssertionError(f"no service endpoint of {fqn} announced in {domain_dir}")


def _answer(sock, seq: int) -> tuple:
    """``(envelope flags, frames)`` of the response to request ``seq``."""
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline:
        if sock.poll(500):
            frames = sock.recv_multipart()
            envelope = unpack_envelope(frames[-1])
            if envelope.seq == seq:
                return envelope.flags, frames
    raise AssertionError(f"no answer to request {seq}")


def test_garbage_requests_are_counted_and_the_next_real_request_is_answered(spawn, domain_dir):
    node = spawn("param_node")
    node.wait_event("ready")
    context = zmq.Context()
    sock = context.socket(zmq.DEALER)
    sock.setsockopt(zmq.LINGER, 0)
    gid = uuid.uuid4().bytes
    try:
        sock.connect(_service_endpoint(domain_dir, "/param_node"))
        sock.send_multipart([b"garbage"])                                                      # too few frames
        sock.send_multipart([b"/param_node/report", os.urandom(5_000_000), b"short envelope"])  # 5 MB, bad envelope
        sock.send_multipart([b"/param_node/report", b"x", pack_envelope(FLAG_RESPONSE, 1, 0, gid)])  # not a request
        sock.send_multipart([b"\xff\xfe", b"x", pack_envelope(FLAG_REQUEST, 2, 0, gid)])   # name not UTF-8
        sock.send_multipart([b"/param_node/report", b"\xc1 not msgpack", pack_envelope(FLAG_REQUEST, 3, 0, gid)])
        flags, frames = _answer(sock, 3)  # undecodable: an error answer, not silence
        assert flags & FLAG_ERROR and flags & FLAG_RESPONSE, frames
        sock.send_multipart(encode("/param_node/report", Trigger.Request())
                            + [pack_envelope(FLAG_REQUEST, 4, time.time_ns(), gid)])
        flags, frames = _answer(sock, 4)
        assert not flags & FLAG_ERROR
        _, response = decode(frames[:-1], expected_type=Trigger.Response)
        assert response.success and json.loads(response.message)["a"] == 0
        assert node.wait_for_stderr("malformed service request (4 so far)"), node.stderr
    finally:
        sock.close(linger=0)
        context.term()


def test_raw_bytes_and_idle_connections_on_the_socket_file_leave_the_service_answering(spawn, domain_dir):
    node = spawn("param_node")
    node.wait_event("ready")
    endpoint = _service_endpoint(domain_dir, "/param_node")
    assert endpoint.startswith("ipc://")
    raw = []
    try:
        for index in range(30):  # not ZMTP at all, a greeting-like prefix with garbage, and silent connections
            connection = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            connection.connect(endpoint[len("ipc://"):])
            if index % 3 == 0:
                connection.sendall(os.urandom(65536))
            elif index % 3 == 1:
                connection.sendall(b"\xff" + bytes(8) + b"\x7f" + os.urandom(200))
            raw.append(connection)
        context = zmq.Context()
        sock = context.socket(zmq.DEALER)
        sock.setsockopt(zmq.LINGER, 0)
        try:
            sock.connect(endpoint)
            sock.send_multipart(encode("/param_node/report", Trigger.Request())
                                + [pack_envelope(FLAG_REQUEST, 1, time.time_ns(), uuid.uuid4().bytes)])
            flags, frames = _answer(sock, 1)  # answered while 30 broken or silent connections are open
            assert not flags & FLAG_ERROR
            assert decode(frames[:-1], expected_type=Trigger.Response)[1].success
        finally:
            sock.close(linger=0)
            context.term()
    finally:
        for connection in raw:
            connection.close()
