"""ZeroMQ plumbing: endpoints, socket set-up, CurveZMQ keys and the envelope frame.

Wire form of one published message (one ZeroMQ multipart message)::

    [topic, header, *arrays]  +  [envelope]
     ^ dptpu.messages.encoder.encode, untouched      ^ 40 bytes, added by the runtime

The envelope carries what the runtime needs and the codec does not: the publisher's id, a sequence
number (gaps = messages dropped in transport; repeats = late-joiner history already seen), the send
time and flags (HISTORY for TRANSIENT_LOCAL replays, REQUEST/RESPONSE/ERROR for services). Service
requests and responses use the same layout with the request id as sequence number.

Configuration (environment variables, read when a context starts its runtime):

==============================  ===================================================================
``DPTPU_TRANSPORT``             ``ipc`` (default): same-host links over Unix sockets; ``tcp``: tcp only
``DPTPU_TCP_INTERFACE``         also bind tcp endpoints on this address (default: none, or
                                127.0.0.1 when ``DPTPU_TRANSPORT=tcp`` or peers are configured)
``DPTPU_TCP_ADVERTISE``         address other hosts use to reach this one (default: the interface, or
                                the host name when the interface is 0.0.0.0)
``DPTPU_CURVE_SECRET_KEY``      a ZeroMQ secret certificate file (``zmq.auth.create_certificates``):
                                every link is CurveZMQ-encrypted and clients are authenticated
``DPTPU_CURVE_AUTHORIZED_KEYS`` folder of the public certificates allowed to connect (required with
                                the secret key; include every participant's, this one's too)
``DPTPU_CURVE``                 ``on`` (default): tcp without the two variables above uses the user's key
                                pair in the discovery folder (:mod:`dptpu.graph.curve_keys`), made when
                                absent; ``off``: tcp without CurveZMQ (a warning says who can then connect)
``DPTPU_SHM``, ``DPTPU_SHM_*``  large messages between processes of one host through shared memory
                                (with the ipc transport; :mod:`dptpu.graph.shared_memory`)
==============================  ===================================================================
"""

from __future__ import annotations

import os
import socket as _socket
import struct
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import zmq

from .curve_keys import ensure_domain_keys
from .shared_memory import SharedMemoryConfig

__all__ = [
    "Envelope", "EnvelopeError", "pack_envelope", "unpack_envelope", "ENVELOPE_SIZE",
    "FLAG_HISTORY", "FLAG_REQUEST", "FLAG_RESPONSE", "FLAG_ERROR",
    "CurveKeys", "TransportConfig", "MAX_IPC_PATH_BYTES",
    "configure_server", "configure_client", "bind_endpoints", "choose_endpoint",
]

_ENVELOPE = struct.Struct("<4sBBHQq16s")
_MAGIC = b"DPGE"
_ENVELOPE_VERSION = 1
ENVELOPE_SIZE = _ENVELOPE.size  # 40 bytes

FLAG_HISTORY = 1    # a TRANSIENT_LOCAL replay of an earlier message
FLAG_REQUEST = 2    # a service request
FLAG_RESPONSE = 4   # a service response
FLAG_ERROR = 8      # a service error response: frames are [service name, UTF-8 reason, envelope]

#: Longest path a Unix socket address holds on Linux (bytes, without the terminating NUL).
MAX_IPC_PATH_BYTES = 107


class EnvelopeError(ValueError):
    """A received frame is not a valid envelope."""


class Envelope(NamedTuple):
    """The runtime's per-message metadata (a named tuple: made once per received message, so cheap).

    Attributes
    ----------
    flags : int
        FLAG_* bits.
    seq : int
        Publisher sequence number (from 1) or service request id.
    stamp_ns : int
        Send time, ns since the Unix epoch.
    gid : bytes
        16-byte id of the publisher or client.
    """

    flags: int
    seq: int
    stamp_ns: int
    gid: bytes


_new_tuple = tuple.__new__


def pack_envelope(flags: int, seq: int, stamp_ns: int, gid: bytes) -> bytes:
    return _ENVELOPE.pack(_MAGIC, _ENVELOPE_VERSION, flags, 0, seq, stamp_ns, gid)


def unpack_envelope(frame) -> Envelope:
    """Parse the last frame of a message; raise :class:`EnvelopeError` when it is not an envelope."""
    data = getattr(frame, "buffer", frame)  # a zmq.Frame's memoryview (no copy), or bytes
    try:
        magic, version, flags, _reserved, seq, stamp_ns, gid = _ENVELOPE.unpack(data)
    except (struct.error, TypeError):
        size = memoryview(data).nbytes if isinstance(data, (bytes, bytearray, memoryview)) else "?"
        raise EnvelopeError(f"envelope frame must have {ENVELOPE_SIZE} bytes; got {size}") from None
    if magic != _MAGIC or version != _ENVELOPE_VERSION:
        raise EnvelopeError(f"envelope has magic {magic!r} version {version}; expected {_MAGIC!r} version "
                            f"{_ENVELOPE_VERSION}")
    return _new_tuple(Envelope, (flags, seq, stamp_ns, gid))  # Envelope(...) without its Python __new__


# --------------------------------------------------------------------------------------------------
# Configuration
# --------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class CurveKeys:
    """This participant's CurveZMQ key pair (Z85 bytes) and the folder of authorized public keys."""

    public: bytes
    secret: bytes
    authorized_keys_dir: Path

    @classmethod
    def load(cls, secret_key_file, authorized_keys_dir) -> CurveKeys:
        """Load a secret certificate file written by ``zmq.auth.create_certificates``.

        Raises
        ------
        ValueError
            When the file has no secret key, or the authorized-keys folder is missing.
        """
        import zmq.auth  # deferred: optional CURVE security; zmq.auth brings asyncio in

        path = Path(secret_key_file)
        try:
            public, secret = zmq.auth.load_certificate(str(path))
        except (OSError, ValueError) as exc:
            raise ValueError(f"cannot load CurveZMQ secret certificate {str(path)!r}: {exc}") from None
        if not secret:
            raise ValueError(f"{str(path)!r} holds no secret key: pass the '.key_secret' file of "
                             "zmq.auth.create_certificates")
        folder = Path(authorized_keys_dir) if authorized_keys_dir else None
        if folder is None or not folder.is_dir():
            raise ValueError("DPTPU_CURVE_AUTHORIZED_KEYS must name a folder of public certificates (.key files) "
                             f"allowed to connect; got {authorized_keys_dir!r}")
        return cls(public, secret, folder)


@dataclass(frozen=True)
class TransportConfig:
    """How this process binds and connects.

    Attributes
    ----------
    local_transport : {"ipc", "tcp"}
        Transport between participants on the same host.
    tcp_interface : str or None
        Address tcp endpoints are bound to (None: no tcp endpoints).
    advertise_host : str or None
        Host or address written into tcp endpoints announced to others.
    curve : CurveKeys or None
        When set, every socket uses CurveZMQ.
    shared_memory : SharedMemoryConfig or None
        Large messages between processes of this host through shared memory (ipc transport only); None: off.
    insecure_tcp : bool
        tcp endpoints without CurveZMQ (``DPTPU_CURVE=off``): the runtime warns.
    """

    local_transport: str = "ipc"
    tcp_interface: str | None = None
    advertise_host: str | None = None
    curve: CurveKeys | None = None
    shared_memory: SharedMemoryConfig | None = None
    insecure_tcp: bool = False

    @classmethod
    def from_environment(cls, env=None, *, want_tcp: bool = False, key_dir: Path | None = None) -> TransportConfig:
        """Read the ``DPTPU_*`` variables (see the module docstring); ``want_tcp`` binds tcp too (peers);
        ``key_dir``: the domain's discovery folder, where tcp's default CurveZMQ keys are kept (None: no default
        keys, tcp without Curve unless configured)."""
        env = os.environ if env is None else env
        local = env.get("DPTPU_TRANSPORT", "ipc").strip().lower() or "ipc"
        if local not in ("ipc", "tcp"):
            raise ValueError(f"DPTPU_TRANSPORT must be 'ipc' or 'tcp'; got {local!r}")
        interface = env.get("DPTPU_TCP_INTERFACE", "").strip() or None
        if interface is None and (local == "tcp" or want_tcp):
            interface = "127.0.0.1"
        advertise = env.get("DPTPU_TCP_ADVERTISE", "").strip() or None
        if advertise is None and interface is not None:
            advertise = _socket.gethostname() if interface in ("0.0.0.0", "*") else interface
        curve = None
        secret_file = env.get("DPTPU_CURVE_SECRET_KEY", "").strip()
        switch = env.get("DPTPU_CURVE", "on").strip().lower() or "on"
        if switch not in ("on", "off"):
            raise ValueError(f"DPTPU_CURVE must be 'on' or 'off'; got {switch!r}")
        if secret_file:
            curve = CurveKeys.load(secret_file, env.get("DPTPU_CURVE_AUTHORIZED_KEYS", "").strip())
        elif interface is not None and switch == "on" and key_dir is not None:
            curve = CurveKeys.load(*ensure_domain_keys(key_dir))
        shared = SharedMemoryConfig.from_environment(env) if local == "ipc" else None
        return cls(local, interface, advertise, curve, shared, insecure_tcp=interface is not None and curve is None)


def configure_server(sock: zmq.Socket, config: TransportConfig) -> None:
    """Make a binding socket a CurveZMQ server when keys are configured; heartbeats for tcp."""
    if config.curve is not None:
        sock.curve_secretkey = config.curve.secret
        sock.curve_publickey = config.curve.public
        sock.curve_server = True
    _heartbeats(sock, config)


def configure_client(sock: zmq.Socket, config: TransportConfig) -> None:
    """Give a connecting socket this participant's CurveZMQ keys (the server key is set per connect)."""
    if config.curve is not None:
        sock.curve_secretkey = config.curve.secret
        sock.curve_publickey = config.curve.public
    _heartbeats(sock, config)


def _heartbeats(sock: zmq.Socket, config: TransportConfig) -> None:
    # ZMTP heartbeats: a silent tcp peer (host powered off, cable pulled) is dropped after ~3 s. Not on ipc only:
    # there the kernel closes a dead peer's socket at once, and a heartbeat would also drop a live peer that is
    # merely paused (SIGSTOP, a long GC) for 3 s, with what its pipes held: a paused projector lost the monitor's
    # start request and the Triggers of the next scan (issue 19)
    if config.tcp_interface is None:
        return
    sock.setsockopt(zmq.HEARTBEAT_IVL, 1000)
    sock.setsockopt(zmq.HEARTBEAT_TIMEOUT, 3000)
    sock.setsockopt(zmq.HEARTBEAT_TTL, 3000)


def connect(sock: zmq.Socket, endpoint: str, config: TransportConfig, server_public_key: str | None) -> None:
    """Connect ``sock`` to ``endpoint``, with the server's Curve key when Curve is on."""
    if config.curve is not None:
        if not server_public_key:
            raise ValueError(f"CurveZMQ is configured but {endpoint} announced no public key")
        sock.curve_serverkey = server_public_key.encode("ascii")
    sock.connect(endpoint)


def bind_endpoints(sock: zmq.Socket, config: TransportConfig, ipc_dir: Path, name: str) -> list[str]:
    """Bind ``sock`` where the configuration says; return the endpoints to announce.

    Parameters
    ----------
    ipc_dir : Path
        Folder of this domain's Unix socket files (private to the user).
    name : str
        Unique file name for the ipc endpoint (e.g. a hex id).

    Returns
    -------
    list of str
        ``ipc:///...`` (when the local transport is ipc) and/or ``tcp://host:port``.
    """
    endpoints = []
    if config.local_transport == "ipc":
        path = str(ipc_dir / name)
        if len(path.encode()) > MAX_IPC_PATH_BYTES:
            raise ValueError(f"ipc socket path {path!r} is longer than {MAX_IPC_PATH_BYTES} bytes; use a shorter "
                             "DPTPU_DISCOVERY_DIR")
        sock.bind(f"ipc://{path}")
        endpoints.append(f"ipc://{path}")
    if config.tcp_interface is not None:
        sock.bind(f"tcp://{config.tcp_interface}:*")
        port = sock.getsockopt_string(zmq.LAST_ENDPOINT).rsplit(":", 1)[1]
        endpoints.append(f"tcp://{config.advertise_host}:{port}")
    return endpoints


def choose_endpoint(endpoints, *, same_host: bool, config: TransportConfig) -> str | None:
    """The endpoint to connect to: ipc on the same host when available, else the first tcp one."""
    endpoints = list(endpoints or [])
    if same_host and config.local_transport == "ipc":
        for endpoint in endpoints:
            if endpoint.startswith("ipc://"):
                return endpoint
    for endpoint in endpoints:
        if endpoint.startswith("tcp://"):
            return endpoint
    return None


def ipc_path(endpoint: str) -> str | None:
    """The socket file of an ``ipc://`` endpoint, else None."""
    return endpoint[len("ipc://"):] if endpoint.startswith("ipc://") else None


def remove_ipc_file(endpoint: str) -> None:
    """Remove the socket file of a dead participant's ipc endpoint (ignores anything else)."""
    path = ipc_path(endpoint)
    if path:
        try:
            os.unlink(path)
        except OSError:
            pass
