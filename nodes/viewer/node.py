"""Viewer node: the live organized point cloud and the status of the last scans, in a browser on localhost.

A stdlib HTTP server (a thread of this process) serves the page of ``static/`` (``index.html``,
``viewer.js`` and three.js 0.187.0 bundled at build time: nothing is fetched from the internet) and a WebSocket
(``/ws``, RFC 6455, :mod:`dptpu.nodes.viewer.websocket`). Each cloud goes to every open page as one binary message
(:func:`pack_cloud`: its finite points, decimated to at most ``max_points``); each ``ScanStatus`` as one JSON
text message. The page draws the points with orbit controls, coloured by depth or by intensity, and lists the
last scans. Design, message format and the browser test: ``docs/viewer.md``.

Topics

===================== =========== ===== =======================================================================
topic                 type        dir   notes
===================== =========== ===== =======================================================================
``/scanner/points``   PointCloud2 in    best effort, depth 2: a slow page skips clouds, the graph never waits
``/scanner/status``   ScanStatus  in    reliable, depth 50
===================== =========== ===== =======================================================================

Parameters

================ =============== ==============================================================================
name             default         meaning
================ =============== ==============================================================================
``host``         "127.0.0.1"     address the HTTP server binds (localhost only by default)
``port``         8765            TCP port (0: any free port; the URL is logged)
``max_points``   150000          clouds are decimated by a whole stride so at most this many pixels are sent
``color_by``     "depth"         first colouring of the page: ``depth`` (z) or ``intensity`` (a button switches)
``idle_timeout_s`` 30.0          a connection that sends no request, or a page that answers no ping, for this
                                 long is closed (pings go out every third of it)
``max_pages``    16              open WebSocket pages at most; one more is refused (503)
================ =============== ==============================================================================

Every parameter is read-only (the server and the page's settings are made at start-up; ``param set`` is refused).

Access (:mod:`dptpu.nodes.viewer.access`): every request must carry the server's own address as ``Host`` (DNS
rebinding), and a WebSocket upgrade with an ``Origin`` must come from the viewer's page (cross-site WebSocket
hijacking); both refusals are 403 and logged. Idle connections are closed after ``idle_timeout_s``.

Run: ``python -m dptpu.nodes.viewer --ros-args -p port:=8765``, then open ``http://127.0.0.1:8765/``.
"""
from __future__ import annotations

import json
import math
import socket
import struct
import threading
import time
from collections import deque
from functools import partial
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import numpy as np

from dptpu.graph.logging import RcutilsLogger
from dptpu.graph.node import Node
from dptpu.graph.parameter_rules import ParameterRules
from dptpu.graph.qos import QoSProfile, ReliabilityPolicy
from dptpu.messages import PointCloud2, ScanStatus
from dptpu.nodes.node_main import run_node

from .access import allowed_hosts, host_problem, origin_problem
from .websocket import (
    OP_BINARY,
    OP_CLOSE,
    OP_PING,
    OP_PONG,
    OP_TEXT,
    ProtocolError,
    accept_key,
    encode_frame,
    read_frame,
)

__all__ = ["ViewerNode", "pack_cloud", "unpack_cloud", "status_record", "CLOUD_MAGIC", "STATIC_DIR", "main"]

STATIC_DIR = Path(__file__).with_name("static")
#: First 4 bytes of a cloud message.
CLOUD_MAGIC = b"DPC1"
_CONTENT_TYPES = {".html": "text/html; charset=utf-8", ".js": "text/javascript; charset=utf-8",
                  ".txt": "text/plain; charset=utf-8", ".css": "text/css; charset=utf-8"}
_STATUS_KEPT = 20
_LEVELS = {0: "OK", 1: "WARN", 2: "ERROR", 3: "STALE"}
_CLOUD_QOS = QoSProfile(depth=2, reliability=ReliabilityPolicy.BEST_EFFORT)


def pack_cloud(cloud: PointCloud2, max_points: int) -> bytes:
    """One cloud as the viewer's binary message: its finite points, decimated, in the camera optical frame.

    Parameters
    ----------
    cloud : PointCloud2
        Organized (H, W) or not; float32/float64 fields ``x, y, z`` in metres (``intensity`` optional).
    max_points : int
        The grid is decimated by the smallest whole stride ``s`` with ``ceil(H/s) * ceil(W/s) <= max_points``.

    Returns
    -------
    bytes
        ``b"DPC1"``, uint32 ``n`` (little-endian), ``n`` bytes of UTF-8 JSON padded with spaces to a multiple of
        4 (``stamp_ns``, ``frame_id``, ``width``, ``height``, ``stride``, ``count``, ``z_range_m``,
        ``intensity_range``), then float32 ``xyz`` (count, 3) in metres, then float32 ``intensity`` (count,)
        (NaN when the cloud has none). Convention: camera optical frame, x right, y down, z forward.

    Raises
    ------
    ValueError
        When the cloud lacks an ``x``, ``y`` or ``z`` field, or ``max_points < 1``.
    """
    if max_points < 1:
        raise ValueError(f"max_points must be >= 1; got {max_points}")
    names = [f.name for f in cloud.fields]
    if not {"x", "y", "z"} <= set(names):
        raise ValueError(f"the viewer needs PointCloud2 fields x, y, z; the cloud has {names}")
    height, width = max(int(cloud.height), 1), int(cloud.width)
    stride = 1
    while math.ceil(height / stride) * math.ceil(width / stride) > max_points:
        stride += 1
    grid = cloud.to_structured().reshape(height, width)[::stride, ::stride]  # (h, w) view of the points
    xyz = np.stack([grid["x"], grid["y"], grid["z"]], axis=-1).astype(np.float32, copy=False)  # (h, w, 3)
    if "intensity" in names:
        intensity = grid["intensity"].astype(np.float32)  # (h, w)
    else:
        intensity = np.full(xyz.shape[:2], np.nan, np.float32)
    finite = np.isfinite(xyz).all(axis=-1)  # (h, w)
    points = np.ascontiguousarray(xyz[finite], dtype="<f4")  # (count, 3)
    values = np.ascontiguousarray(intensity[finite], dtype="<f4")  # (count,)
    stamp = cloud.header.stamp
    meta = {"stamp_ns": int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec), "frame_id": cloud.header.frame_id,
            "width": width, "height": height, "stride": stride, "count": int(points.shape[0]),
            "z_range_m": _range(points[:, 2]), "intensity_range": _range(values)}
    text = json.dumps(meta).encode("utf-8")
    text += b" " * (-len(text) % 4)
    return b"".join([CLOUD_MAGIC, struct.pack("<I", len(text)), text, points.tobytes(), values.tobytes()])


def _range(values: np.ndarray) -> list:
    finite = values[np.isfinite(values)]
    return [float(finite.min()), float(finite.max())] if finite.size else [0.0, 0.0]


def unpack_cloud(payload: bytes) -> tuple[dict, np.ndarray, np.ndarray]:
    """Inverse of :func:`pack_cloud`: ``(meta, xyz (count, 3) float32, intensity (count,) float32)``.

    Raises
    ------
    ValueError
        When the magic, the JSON or the sizes do not fit.
    """
    if payload[:4] != CLOUD_MAGIC or len(payload) < 8:
        raise ValueError(f"a viewer cloud message starts with {CLOUD_MAGIC!r}; got {bytes(payload[:4])!r}")
    (size,) = struct.unpack_from("<I", payload, 4)
    meta = json.loads(bytes(payload[8:8 + size]))
    count = meta["count"]
    body = np.frombuffer(payload, dtype="<f4", offset=8 + size)
    if body.size != 4 * count:
        raise ValueError(f"a viewer cloud of {count} points needs {16 * count} bytes of points; got {4 * body.size}")
    return meta, body[:3 * count].reshape(count, 3), body[3 * count:]


def status_record(status: ScanStatus) -> dict:
    """The JSON record of one ScanStatus the page lists (``type: status``)."""
    stamp = status.header.stamp
    return {"type": "status", "sequence_id": int(status.sequence_id), "level": _LEVELS.get(status.level, "?"),
            "state": status.state, "node": status.node, "reason": status.reason,
            "valid_pixels": int(status.valid_pixels), "total_pixels": int(status.total_pixels),
            "duration_s": float(status.duration_s), "stamp_ns": int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)}


class _Broadcast:
    """What every page gets: the latest cloud (pages skip older ones) and the last statuses, with counters."""

    def __init__(self, config: str):
        self.config = config  # JSON text every page gets first
        self.cond = threading.Condition()
        self.cloud: bytes | None = None
        self.cloud_version = 0
        self.statuses: deque = deque(maxlen=_STATUS_KEPT)  # (number, json text)
        self.status_count = 0
        self.closed = False

    def put_cloud(self, payload: bytes) -> None:
        with self.cond:
            self.cloud, self.cloud_version = payload, self.cloud_version + 1
            self.cond.notify_all()

    def put_status(self, text: str) -> None:
        with self.cond:
            self.status_count += 1
            self.statuses.append((self.status_count, text))
            self.cond.notify_all()

    def close(self) -> None:
        with self.cond:
            self.closed = True
            self.cond.notify_all()


class _Handler(BaseHTTPRequestHandler):
    """GET ``/`` and the static files; GET ``/ws`` upgrades to the WebSocket feed."""

    server: _ViewerServer
    server_version = "dptpu-viewer"
    protocol_version = "HTTP/1.1"

    def log_message(self, format, *args):  # BaseHTTPRequestHandler's signature
        self.server.node_logger.debug("http: " + format % args)

    def setup(self):  # StreamRequestHandler's hook: the socket's timeout before any request line is read
        self.timeout = self.server.idle_timeout_s
        super().setup()

    def do_GET(self):  # BaseHTTPRequestHandler's name
        problem = host_problem(self.headers.get("Host"), self.server.allowed_hosts)
        if problem is not None:
            self._refuse(HTTPStatus.FORBIDDEN, problem)
            return
        path = self.path.split("?", 1)[0]
        if path == "/ws":
            self._websocket()
            return
        name = "index.html" if path == "/" else path.lstrip("/")
        file = self.server.static_files.get(name)
        if file is None:
            self.send_error(HTTPStatus.NOT_FOUND, f"no such file: {path}")
            return
        body = file.read_bytes()
        self.send_response(HTTPStatus.OK)
        self.send_header("Content-Type", _CONTENT_TYPES.get(file.suffix, "application/octet-stream"))
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.end_headers()
        self.wfile.write(body)

    def _refuse(self, status: HTTPStatus, problem: str) -> None:
        self.server.node_logger.warning(f"viewer: refused a request from {self.client_address[0]}: {problem}",
                                        throttle_duration_sec=5.0)
        self.send_error(status, problem)

    def _websocket(self) -> None:
        if self.headers.get("Upgrade", "").lower() != "websocket":
            self.send_error(HTTPStatus.BAD_REQUEST, "/ws is a WebSocket endpoint (Upgrade: websocket)")
            return
        problem = origin_problem(self.headers.get("Origin"), self.server.allowed_hosts)
        if problem is not None:
            self._refuse(HTTPStatus.FORBIDDEN, problem)
            return
        if not self.server.pages.acquire(blocking=False):
            self._refuse(HTTPStatus.SERVICE_UNAVAILABLE, f"{self.server.max_pages} pages are open already (max_pages)")
            return
        try:
            self._upgrade()
        finally:
            self.server.pages.release()

    def _upgrade(self) -> None:
        try:
            accept = accept_key(self.headers.get("Sec-WebSocket-Key", ""))
        except ValueError as exc:
            self.send_error(HTTPStatus.BAD_REQUEST, str(exc))
            return
        self.send_response(HTTPStatus.SWITCHING_PROTOCOLS)
        self.send_header("Upgrade", "websocket")
        self.send_header("Connection", "Upgrade")
        self.send_header("Sec-WebSocket-Accept", accept)
        self.end_headers()
        self.close_connection = True
        _Session(self.server, self.rfile, self.wfile, self.connection, self.server.idle_timeout_s).run()


class _ViewerServer(ThreadingHTTPServer):
    """The viewer's HTTP server: one thread per request, and what its handlers share."""

    daemon_threads = True

    def __init__(self, address: tuple[str, int], broadcast: _Broadcast, static_files: dict[str, Path],
                 node_logger: RcutilsLogger, *, idle_timeout_s: float, max_pages: int):
        super().__init__(address, _Handler)
        self.broadcast = broadcast
        self.static_files = static_files
        self.node_logger = node_logger
        self.idle_timeout_s = idle_timeout_s
        self.max_pages = max_pages
        self.pages = threading.BoundedSemaphore(max_pages)
        self.allowed_hosts = allowed_hosts(address[0], self.server_address[1])


class _Session:
    """One page: this thread sends clouds and statuses; a reader thread answers pings and sees the close."""

    def __init__(self, server: _ViewerServer, rfile, wfile, connection, idle_timeout_s: float):
        self.broadcast: _Broadcast = server.broadcast
        self.logger = server.node_logger
        self.rfile, self.wfile, self.connection = rfile, wfile, connection
        self.send_lock = threading.Lock()
        self.open = True
        # a read (or a send) that waits this long ends the page: a live browser answers the pings long before
        self.ping_interval_s = idle_timeout_s / 3.0
        connection.settimeout(idle_timeout_s)

    def send(self, opcode: int, payload) -> None:
        with self.send_lock:
            for part in encode_frame(opcode, payload):
                self.wfile.write(part)
            self.wfile.flush()

    def read_loop(self) -> None:
        try:
            while self.open:
                opcode, payload = read_frame(self.rfile)
                if opcode == OP_PING:
                    self.send(OP_PONG, payload)
                elif opcode == OP_CLOSE:
                    self.send(OP_CLOSE, payload[:2])
                    break
        except ProtocolError as exc:
            self.logger.warning(f"closing a viewer page: {exc}")
            try:
                self.send(OP_CLOSE, struct.pack("!H", exc.code))
            except OSError:
                pass
        except (EOFError, OSError, ValueError):
            pass
        self.open = False
        with self.broadcast.cond:
            self.broadcast.cond.notify_all()

    def _news_since(self, sent_cloud: int, sent_status: int) -> bool:
        """True when the page closed, the node stops, or a cloud or status came after those sent."""
        return (not self.open or self.broadcast.closed or self.broadcast.cloud_version != sent_cloud
                or self.broadcast.status_count != sent_status)

    def run(self) -> None:
        threading.Thread(target=self.read_loop, daemon=True, name="viewer-ws-reader").start()
        sent_cloud, sent_status = 0, 0
        next_ping_s = time.monotonic() + self.ping_interval_s
        try:
            self.send(OP_TEXT, self.broadcast.config.encode("utf-8"))
            while True:
                if time.monotonic() >= next_ping_s:
                    self.send(OP_PING, b"")
                    next_ping_s = time.monotonic() + self.ping_interval_s
                with self.broadcast.cond:
                    self.broadcast.cond.wait_for(partial(self._news_since, sent_cloud, sent_status),
                                                 timeout=min(5.0, max(0.0, next_ping_s - time.monotonic())))
                    if not self.open or self.broadcast.closed:
                        break
                    statuses = [text for number, text in self.broadcast.statuses if number > sent_status]
                    sent_status = self.broadcast.status_count
                    cloud = self.broadcast.cloud if self.broadcast.cloud_version != sent_cloud else None
                    sent_cloud = self.broadcast.cloud_version
                for text in statuses:
                    self.send(OP_TEXT, text.encode("utf-8"))
                if cloud is not None:
                    self.send(OP_BINARY, cloud)
            if self.open:
                self.send(OP_CLOSE, struct.pack("!H", 1001))  # going away: the node stops
        except OSError:
            pass
        finally:
            self.open = False
            try:
                self.connection.shutdown(socket.SHUT_RDWR)  # ends the reader thread's read at once
            except OSError:
                pass


class ViewerNode(Node):
    """PointCloud2 and ScanStatus -> a web page over a WebSocket (see the module docstring)."""

    def __init__(self, node_name: str = "viewer", **node_options):
        super().__init__(node_name, **node_options)
        rules = ParameterRules(self)
        host = rules.read_only("host", "127.0.0.1", description="the server's address")
        port = rules.read_only("port", 8765, description="the server's port")
        page = "sent to each page as it connects; restart the node to change it"
        self.max_points = rules.read_only("max_points", 150000, description=page)
        self.color_by = rules.read_only("color_by", "depth", description=page)
        idle_timeout_s = rules.read_only("idle_timeout_s", 30.0, description="closing idle connections")
        max_pages = rules.read_only("max_pages", 16, description="open WebSocket pages at most")
        if not 0 <= port <= 65535:
            raise ValueError(f"parameter port must be 0..65535 (0: any free port); got {port}")
        if self.max_points < 1:
            raise ValueError(f"parameter max_points must be >= 1; got {self.max_points}")
        if self.color_by not in ("depth", "intensity"):
            raise ValueError(f"parameter color_by must be 'depth' or 'intensity'; got {self.color_by!r}")
        if not idle_timeout_s > 0:
            raise ValueError(f"parameter idle_timeout_s must be > 0 seconds; got {idle_timeout_s}")
        if max_pages < 1:
            raise ValueError(f"parameter max_pages must be >= 1; got {max_pages}")
        static_files = {p.name: p for p in STATIC_DIR.iterdir() if p.is_file()}
        if "index.html" not in static_files:
            raise OSError(f"the viewer's page is missing: {STATIC_DIR / 'index.html'} (a broken install?)")
        self.clouds_received = 0
        self.clouds_rejected = 0
        self.broadcast = _Broadcast(json.dumps({"type": "config", "color_by": self.color_by,
                                                "max_points": self.max_points}))

        self.server = _ViewerServer((host, port), self.broadcast, static_files, self.get_logger(),
                                    idle_timeout_s=float(idle_timeout_s), max_pages=int(max_pages))
        self.port = self.server.server_address[1]
        self.url = f"http://{host}:{self.port}/"
        self._server_thread = threading.Thread(target=self.server.serve_forever, kwargs={"poll_interval": 0.2},
                                               daemon=True, name="viewer-http")
        self._server_thread.start()
        self.get_logger().info(f"viewer at {self.url}")

        self.cloud_subscription = self.create_subscription(PointCloud2, "/scanner/points", self.on_cloud, _CLOUD_QOS)
        self.status_subscription = self.create_subscription(ScanStatus, "/scanner/status", self.on_status, 50)

    def on_cloud(self, msg: PointCloud2) -> None:
        """Pack the cloud once; every page's sender takes the newest."""
        try:
            payload = pack_cloud(msg, self.max_points)
        except ValueError as exc:
            self.clouds_rejected += 1
            self.get_logger().warning(f"cannot show a cloud: {exc}", throttle_duration_sec=5.0)
            return
        self.clouds_received += 1
        self.broadcast.put_cloud(payload)

    def on_status(self, msg: ScanStatus) -> None:
        self.broadcast.put_status(json.dumps(status_record(msg)))

    def destroy_node(self) -> None:
        self.broadcast.close()
        self.server.shutdown()
        self.server.server_close()
        super().destroy_node()


def main(argv=None) -> int:
    """``python -m dptpu.nodes.viewer --ros-args -p port:=8765``: serve until Ctrl-C or SIGTERM."""
    return run_node("viewer", ViewerNode, argv)

