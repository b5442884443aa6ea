"""The viewer's server without a browser: RFC 6455 pieces, the cloud message, and the node as a process heard by a
minimal WebSocket client written here (stdlib sockets)."""
from __future__ import annotations

import base64
import io
import json
import os
import socket
import struct
import threading
import time
import urllib.error
import urllib.request

import numpy as np
import pytest

from dptpu.messages import Header, PointCloud2, ScanStatus, Time
from dptpu.nodes.harness import NodeHarness
from dptpu.nodes.viewer import ViewerNode
from dptpu.nodes.viewer.node import STATIC_DIR, pack_cloud, unpack_cloud
from dptpu.nodes.viewer.websocket import OP_PING, OP_TEXT, ProtocolError, accept_key, encode_frame, read_frame


def test_accept_key_is_rfc_6455_example():
    # RFC 6455 section 1.3: the sample nonce and its accept value
    assert accept_key("dGhlIHNhbXBsZSBub25jZQ==") == "s3pPLMBiTxaQ9kYGzzhZRbK+xOo="
    with pytest.raises(ValueError, match="base64 text of 16 bytes"):
        accept_key("c2hvcnQ=")


def _client_frame(opcode: int, payload: bytes, mask=b"\x37\xfa\x21\x3d", *, masked=True) -> bytes:
    size = len(payload)
    head = struct.pack("!B", 0x80 | opcode)
    head += struct.pack("!B", (0x80 if masked else 0) | (size if size < 126 else 126))
    if size >= 126:
        head += struct.pack("!H", size)
    if not masked:
        return head + payload
    body = bytes(b ^ mask[i % 4] for i, b in enumerate(payload))
    return head + mask + body


def test_frames_round_trip_and_bad_client_frames_are_refused():
    # RFC 6455 section 5.7: a masked "Hello" from a client
    assert read_frame(io.BytesIO(bytes.fromhex("818537fa213d7f9f4d5158"))) == (OP_TEXT, b"Hello")
    payload = bytes(range(256)) * 2  # 512 bytes: the 16-bit length form
    assert read_frame(io.BytesIO(_client_frame(OP_PING, payload))) == (OP_PING, payload)
    assert b"".join(encode_frame(OP_TEXT, b"Hello")) == bytes.fromhex("810548656c6c6f")  # RFC's unmasked example
    assert b"".join(encode_frame(0x2, b"x" * 70000))[:10] == b"\x82\x7f" + struct.pack("!Q", 70000)
    with pytest.raises(ProtocolError, match="must be masked"):
        read_frame(io.BytesIO(_client_frame(OP_TEXT, b"hi", masked=False)))
    with pytest.raises(ProtocolError, match="fragmented"):
        read_frame(io.BytesIO(b"\x01\x80" + b"\x00" * 4))
    with pytest.raises(EOFError):
        read_frame(io.BytesIO(b"\x81"))


def _cloud(width: int, height: int) -> PointCloud2:
    """x, y, z, intensity float32 with a NaN hole every 7th pixel (same finite count for any check)."""
    v, u = np.mgrid[0:height, 0:width].astype(np.float32)  # (H, W) pixel rows, columns
    points = np.stack([(u - width / 2) * 1e-3, (v - height / 2) * 1e-3, 0.8 + 1e-4 * u, u + v], axis=-1)  # (H, W, 4)
    points[(np.arange(height * width) % 7 == 0).reshape(height, width), :3] = np.nan
    return PointCloud2.from_array(points.astype(np.float32), ["x", "y", "z", "intensity"],
                                  header=Header(stamp=Time(sec=12, nanosec=34), frame_id="scanner_optical_frame"))


def test_pack_cloud_sends_the_finite_points_of_the_decimated_grid():
    cloud = _cloud(40, 30)
    meta, xyz, intensity = unpack_cloud(pack_cloud(cloud, max_points=1200))
    grid = cloud.to_array(["x", "y", "z", "intensity"])  # (30, 40, 4)
    finite = np.isfinite(grid[..., :3]).all(axis=-1)
    assert meta["stride"] == 1 and meta["count"] == int(finite.sum()) == 1200 - 172
    np.testing.assert_array_equal(xyz, grid[..., :3][finite])
    np.testing.assert_array_equal(intensity, grid[..., 3][finite])
    assert meta["stamp_ns"] == 12_000_000_034 and meta["z_range_m"] == pytest.approx([0.8, 0.8039], abs=1e-6)
    meta, xyz, _ = unpack_cloud(pack_cloud(cloud, max_points=300))  # ceil(30/2) * ceil(40/2) = 300
    assert meta["stride"] == 2
    np.testing.assert_array_equal(xyz, grid[::2, ::2, :3][np.isfinite(grid[::2, ::2, :3]).all(axis=-1)])
    assert unpack_cloud(pack_cloud(cloud, max_points=299))[0]["stride"] == 3
    with pytest.raises(ValueError, match="needs PointCloud2 fields x, y, z"):
        pack_cloud(PointCloud2.from_array(np.zeros((2, 2, 1), np.float32), ["depth"]), 10)


class WebSocketClient:
    """A minimal RFC 6455 client: handshake, masked close, unmasked server frames read."""

    def __init__(self, port: int):
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=20)
        key = base64.b64encode(os.urandom(16)).decode()
        self.sock.sendall((f"GET /ws HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\n"
                           f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n\r\n")
                          .encode())
        self.stream = self.sock.makefile("rb")
        status = self.stream.readline()
        headers = {}
        while (line := self.stream.readline()) not in (b"\r\n", b""):
            name, _, value = line.decode().partition(":")
            headers[name.strip().lower()] = value.strip()
        assert status.startswith(b"HTTP/1.1 101"), status
        assert headers["sec-websocket-accept"] == accept_key(key)

    def receive(self) -> tuple[int, bytes]:
        first, second = self.stream.read(2)
        size = second & 0x7F
        if size == 126:
            size = struct.unpack("!H", self.stream.read(2))[0]
        elif size == 127:
            size = struct.unpack("!Q", self.stream.read(8))[0]
        return first & 0x0F, self.stream.read(size)

    def close(self) -> None:
        self.sock.sendall(_client_frame(0x8, struct.pack("!H", 1000)))
        self.sock.close()


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_viewer_process_serves_the_page_and_streams_clouds_and_statuses(spawn_node, probe):
    port = _free_port()
    viewer = spawn_node("dptpu.nodes.viewer", "--ros-args", "-p", f"port:={port}", "-p", "max_points:=300")
    assert viewer.wait_for_stderr(f"viewer at http://127.0.0.1:{port}/", timeout=30), viewer.stderr
    page = urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=10).read().decode()
    assert '<script type="module" src="viewer.js">' in page
    bundle = urllib.request.urlopen(f"http://127.0.0.1:{port}/three.bundle.min.js", timeout=10).read()
    assert bundle == (STATIC_DIR / "three.bundle.min.js").read_bytes()
    for path in ("/../viewer.py", "/viewer.py", "/ws2"):
        with pytest.raises(urllib.error.HTTPError, match="404"):
            urllib.request.urlopen(f"http://127.0.0.1:{port}{path}", timeout=10)

    client = WebSocketClient(port)
    try:
        opcode, payload = client.receive()
        assert opcode == OP_TEXT and json.loads(payload) == {"type": "config", "color_by": "depth", "max_points": 300}
        points = probe.publisher(PointCloud2, "/scanner/points", 10)
        statuses = probe.publisher(ScanStatus, "/scanner/status", 50)
        assert points.wait_for_subscriptions(1, timeout_sec=20) and statuses.wait_for_subscriptions(1, timeout_sec=20)
        cloud = _cloud(40, 30)
        statuses.publish(ScanStatus(sequence_id=5, level=0, state="done", node="/cloud", valid_pixels=1028,
                                    total_pixels=1200, duration_s=0.25))
        points.publish(cloud)
        got = {}
        deadline = time.monotonic() + 20
        while len(got) < 2 and time.monotonic() < deadline:
            opcode, payload = client.receive()
            got[opcode] = payload
        status = json.loads(got[OP_TEXT])
        assert (status["sequence_id"], status["state"], status["level"], status["valid_pixels"]) == (5, "done", "OK",
                                                                                                     1028)
        meta, xyz, _ = unpack_cloud(got[0x2])
        assert meta["stride"] == 2 and meta["width"] == 40 and meta["height"] == 30
        grid = cloud.to_array(["x", "y", "z"])[::2, ::2]
        np.testing.assert_array_equal(xyz, grid[np.isfinite(grid).all(axis=-1)])
    finally:
        client.close()


def test_viewer_refuses_bad_parameters_naming_them(spawn_node):
    with NodeHarness() as harness:
        with pytest.raises(ValueError, match="parameter color_by must be 'depth' or 'intensity'; got 'rainbow'"):
            harness.start(ViewerNode, color_by="rainbow")
        with pytest.raises(ValueError, match="parameter max_points must be >= 1; got 0"):
            harness.start(ViewerNode, max_points=0)
    viewer = spawn_node("dptpu.nodes.viewer", "--ros-args", "-p", "port:=70000")
    assert viewer.wait(timeout=30) == 2
    assert "viewer: error: parameter port must be 0..65535 (0: any free port); got 70000" in viewer.stderr


def _raw_request(port: int, request: str) -> bytes:
    with socket.create_connection(("127.0.0.1", port), timeout=20) as sock:
        sock.sendall(request.encode())
        return sock.makefile("rb").readline()


def _upgrade(port: int, host: str, origin: str | None) -> str:
    key = base64.b64encode(os.urandom(16)).decode()
    origin_line = f"Origin: {origin}\r\n" if origin is not None else ""
    return (f"GET /ws HTTP/1.1\r\nHost: {host}\r\n{origin_line}Upgrade: websocket\r\nConnection: Upgrade\r\n"
            f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n\r\n")


def test_foreign_host_and_origin_are_refused_and_the_own_page_is_served():
    """DNS rebinding (a foreign Host) and cross-site WebSocket hijacking (a foreign Origin) get 403 (issue 19)."""
    with NodeHarness() as harness:
        viewer = harness.start(ViewerNode, port=0)
        port = viewer.port
        assert _raw_request(port, f"GET / HTTP/1.1\r\nHost: evil.example:{port}\r\n\r\n").startswith(b"HTTP/1.1 403")
        assert _raw_request(port, "GET / HTTP/1.1\r\n\r\n").startswith(b"HTTP/1.1 403")  # no Host at all
        assert _raw_request(port, f"GET / HTTP/1.1\r\nHost: localhost:{port}\r\n\r\n").startswith(b"HTTP/1.1 200")
        assert _raw_request(port, _upgrade(port, f"127.0.0.1:{port}", "http://evil.example")).startswith(
            b"HTTP/1.1 403")
        assert _raw_request(port, _upgrade(port, f"127.0.0.1:{port}", f"http://127.0.0.1:{port + 1}")).startswith(
            b"HTTP/1.1 403")  # another local server's page
        for origin in (f"http://127.0.0.1:{port}", f"http://localhost:{port}", None):
            assert _raw_request(port, _upgrade(port, f"127.0.0.1:{port}", origin)).startswith(b"HTTP/1.1 101")


def _viewer_threads() -> int:
    return sum(1 for t in threading.enumerate() if t.name.startswith(("viewer-ws", "Thread-")) and t.is_alive())


def test_idle_connections_are_closed_and_their_threads_end():
    """300 idle connections once left 274 threads (issue 19): a socket that never sends a request, and a
    WebSocket page that never answers a ping, are closed after idle_timeout_s."""
    with NodeHarness() as harness:
        viewer = harness.start(ViewerNode, port=0, idle_timeout_s=1.0, max_pages=2)
        port = viewer.port
        before = _viewer_threads()
        silent = [socket.create_connection(("127.0.0.1", port), timeout=20) for _ in range(20)]
        pages = []
        for _ in range(2):  # each page asks at once (one opened before the other's answer sat idle: closed under load)
            page = socket.create_connection(("127.0.0.1", port), timeout=20)
            page.sendall(_upgrade(port, f"127.0.0.1:{port}", None).encode())
            assert page.makefile("rb").readline().startswith(b"HTTP/1.1 101")
            pages.append(page)
        # a third page is refused while both are open
        assert _raw_request(port, _upgrade(port, f"127.0.0.1:{port}", None)).startswith(b"HTTP/1.1 503")
        deadline = time.monotonic() + 30
        closed = set()
        while len(closed) < len(silent) + len(pages) and time.monotonic() < deadline:
            for index, sock in enumerate(silent + pages):
                sock.settimeout(0.2)
                try:
                    while sock.recv(65536):  # a page gets its config and pings first; b"" = closed by the server
                        pass
                    closed.add(index)
                except TimeoutError:
                    pass
                except OSError:
                    closed.add(index)
        assert len(closed) == len(silent) + len(pages)
        harness.spin_until(lambda: _viewer_threads() <= before, 10.0)
        assert _viewer_threads() <= before
        # once they are gone a page is accepted again
        assert _raw_request(port, _upgrade(port, f"127.0.0.1:{port}", None)).startswith(b"HTTP/1.1 101")
        for sock in silent + pages:
            sock.close()
