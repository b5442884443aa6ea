"""Discovery across hosts: one process per host exchanges announcements with the peer hosts listed.

Configuration (environment)::

    DPTPU_PEERS=10.0.0.2:7400,10.0.0.3:7400        peer hosts' exchange ports
    DPTPU_PEERS=10.0.0.2:7400=/etc/dptpu/b.key     ... with the peer's public certificate (CurveZMQ)
    DPTPU_DISCOVERY_PORT=7400                      this host's exchange port (default 7400)
    DPTPU_TCP_INTERFACE=10.0.0.1                   where to bind (default 127.0.0.1)

When peers are configured every process also binds tcp endpoints (``transport``). Whichever process
of a host binds the exchange port first becomes that host's exchanger (the others retry every two
seconds, so another takes over when it exits). Once a second the exchanger sends every peer the
announcements of its host's nodes (one msgpack-free JSON message); a receiving exchanger writes them
into its own discovery folder as ``n-r-...json`` files with an expiry time five seconds ahead, so every
process of that host discovers the remote nodes exactly like local ones, and connects over tcp.
Entries learnt from a peer are never forwarded (no loops); entries not refreshed expire.
"""

from __future__ import annotations

import hashlib
import json
import os
import time
from dataclasses import dataclass
from pathlib import Path

import zmq

from .discovery import remove_announcement, write_announcement
from .transport import connect

__all__ = ["PeerConfig", "PeerExchange", "peers_from_environment", "parse_peers", "PEER_EXPIRY_S", "DEFAULT_PORT"]

DEFAULT_PORT = 7400
PEER_EXPIRY_S = 5.0
_PROTOCOL = b"dptpu-peers/1"
_MAX_MESSAGE_BYTES = 8 << 20


@dataclass(frozen=True)
class PeerConfig:
    """Where this host listens and which peers it talks to: ``peers`` is ``((address, public_key or None), ...)``."""

    port: int
    peers: tuple


def parse_peers(text: str) -> tuple:
    """``"h1:7400,h2:7400=/keys/h2.key"`` -> ``(("tcp://h1:7400", None), ("tcp://h2:7400", b"<z85 key>"))``."""
    peers = []
    for item in filter(None, (part.strip() for part in text.split(","))):
        address, _, key_file = item.partition("=")
        host, sep, port = address.rpartition(":")
        if not sep or not host or not port.isdigit():
            raise ValueError(f"DPTPU_PEERS items must look like host:port (optionally =public.key); got {item!r}")
        key = None
        if key_file:
            import zmq.auth  # deferred: optional CURVE security; zmq.auth brings asyncio in

            try:
                key, _ = zmq.auth.load_certificate(key_file)
            except (OSError, ValueError) as exc:
                raise ValueError(f"cannot load the peer certificate {key_file!r}: {exc}") from None
        peers.append((f"tcp://{host}:{int(port)}", key))
    return tuple(peers)


def peers_from_environment(env=None) -> PeerConfig | None:
    env = os.environ if env is None else env
    text = env.get("DPTPU_PEERS", "").strip()
    if not text:
        return None
    port_text = env.get("DPTPU_DISCOVERY_PORT", "").strip() or str(DEFAULT_PORT)
    if not port_text.isdigit() or not 0 < int(port_text) < 65536:
        raise ValueError(f"DPTPU_DISCOVERY_PORT must be a port number; got {port_text!r}")
    return PeerConfig(int(port_text), parse_peers(text))


class PeerExchange:
    """The runtime's side of the peer exchange (runs on the I/O thread)."""

    def __init__(self, runtime, config: PeerConfig):
        self.runtime = runtime
        self.config = config
        self._server = None
        self._clients: list = []
        self._next_bind_attempt = 0.0
        self._files_by_origin: dict[str, set] = {}

    def changed(self) -> bool:
        return False  # remote entries arrive as files in the discovery folder

    def entries(self) -> list:
        return []

    def step(self) -> None:
        """Once a second: become the exchanger if the port is free; send this host's announcements."""
        now = time.monotonic()
        if self._server is None and now >= self._next_bind_attempt:
            self._try_bind()
            self._next_bind_attempt = now + 2.0
        if self._server is not None:
            self._send_local()

    def _try_bind(self) -> None:
        runtime = self.runtime
        transport = runtime.transport
        sock = runtime.zmq_context.socket(zmq.ROUTER)
        sock.setsockopt(zmq.LINGER, 0)
        sock.setsockopt(zmq.MAXMSGSIZE, _MAX_MESSAGE_BYTES)
        if transport.curve is not None:
            sock.curve_secretkey = transport.curve.secret
            sock.curve_publickey = transport.curve.public
            sock.curve_server = True
        try:
            sock.bind(f"tcp://{transport.tcp_interface}:{self.config.port}")
        except zmq.ZMQError:
            sock.close(linger=0)
            return  # another process of this host is the exchanger
        self._server = sock
        runtime._handlers[sock] = self._on_message
        runtime._poller.register(sock, zmq.POLLIN)
        for address, key in self.config.peers:
            client = runtime.zmq_context.socket(zmq.DEALER)
            client.setsockopt(zmq.LINGER, 0)
            client.setsockopt(zmq.SNDHWM, 4)
            client.setsockopt(zmq.IMMEDIATE, 1)
            if transport.curve is not None:
                client.curve_secretkey = transport.curve.secret
                client.curve_publickey = transport.curve.public
            if not key and transport.curve is not None:  # a peer without a listed key shares this host's pair
                key = transport.curve.public
            connect(client, address, transport, key.decode("ascii") if key else None)
            self._clients.append(client)

    def _send_local(self) -> None:
        runtime = self.runtime
        local = [e for e in runtime.entries if not e.get("via") and e.get("host") == runtime.host
                 and e.get("boot_id") == runtime.boot_id]
        payload = json.dumps({"host": runtime.host, "boot_id": runtime.boot_id, "domain_id": runtime.domain_id,
                              "folder": str(runtime.directory), "entries": local}, separators=(",", ":")).encode()
        for client in self._clients:
            try:
                client.send_multipart([_PROTOCOL, payload], flags=zmq.NOBLOCK)
            except zmq.Again:
                pass  # peer unreachable now; next second

    def _on_message(self, frames):
        if len(frames) != 3 or frames[1].bytes != _PROTOCOL:
            return None
        try:
            message = json.loads(frames[2].bytes)
            origin = f"{message['host']}|{message['boot_id']}|{message.get('folder')}"
            entries = message["entries"]
            if message["domain_id"] != self.runtime.domain_id or not isinstance(entries, list):
                return None
        except (ValueError, KeyError, TypeError):
            return None
        if (message["host"], message["boot_id"], message.get("folder")) == (
                self.runtime.host, self.runtime.boot_id, str(self.runtime.directory)):
            return None  # our own announcements (a peer list naming this host)
        tag = hashlib.sha1(origin.encode()).hexdigest()[:10]
        expires = time.time() + PEER_EXPIRY_S
        written = set()
        for entry in entries:
            if not isinstance(entry, dict) or not isinstance(entry.get("gid"), str):
                continue
            entry = dict(entry, via="peer", expires=expires)
            name = f"n-r-{tag}-{entry['gid'][:32]}.json"
            write_announcement(Path(self.runtime.directory), name, entry)
            written.add(name)
        for name in self._files_by_origin.get(origin, set()) - written:
            remove_announcement(Path(self.runtime.directory), name)
        self._files_by_origin[origin] = written
        return None

    def close(self) -> None:
        for name_set in self._files_by_origin.values():
            for name in name_set:
                remove_announcement(Path(self.runtime.directory), name)
        self._files_by_origin.clear()
