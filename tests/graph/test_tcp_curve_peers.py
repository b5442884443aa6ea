"""The tcp transport (127.0.0.1 only), CurveZMQ authentication, and discovery through a peer exchange."""

from __future__ import annotations

import contextlib
import os
import shutil
import socket
import tempfile

import zmq.auth

from dptpu.graph.discovery import get_graph


def test_tcp_transport_binds_loopback_and_delivers(spawn, domain_dir):
    env = {"DPTPU_TRANSPORT": "tcp"}  # CurveZMQ with the keys made in the discovery folder (below)
    listener = spawn("listener", "--count", "3", "--linger", "2", env=env)
    listener.wait_event("ready")
    talker = spawn("talker", "--count", "3", "--wait-subs", "1", "--linger", "2", env=env)
    assert talker.wait_event("published")["count"] == 3
    assert listener.wait_event("done")["received"] == ["0", "1", "2"]
    endpoints = get_graph(directory=domain_dir).topics["/chatter"].publishers[0].endpoints
    assert len(endpoints) == 1 and endpoints[0].startswith("tcp://127.0.0.1:")


def test_curve_lets_authorized_keys_in_and_keeps_others_out(spawn, tmp_path):
    keys = tmp_path / "keys"
    authorized = tmp_path / "authorized"
    keys.mkdir()
    authorized.mkdir()
    trusted_public, trusted_secret = zmq.auth.create_certificates(str(keys), "trusted")
    _, stranger_secret = zmq.auth.create_certificates(str(keys), "stranger")
    (authorized / "trusted.key").write_bytes(open(trusted_public, "rb").read())

    def env(secret):
        return {"DPTPU_TRANSPORT": "tcp", "DPTPU_CURVE_SECRET_KEY": secret,
                "DPTPU_CURVE_AUTHORIZED_KEYS": str(authorized)}

    friend = spawn("listener", "--name", "friend", "--count", "3", env=env(trusted_secret))
    stranger = spawn("listener", "--name", "stranger", "--timeout", "2.0", env=env(stranger_secret))
    friend.wait_event("ready")
    stranger.wait_event("ready")
    talker = spawn("talker", "--count", "3", "--wait-subs", "1", "--linger", "1.5", env=env(trusted_secret))
    assert talker.wait_event("published")["count"] == 3
    assert friend.wait_event("done")["received"] == ["0", "1", "2"]
    assert stranger.wait_event("done")["received"] == []


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def test_peer_exchange_discovers_nodes_of_another_discovery_domain_folder(spawn):
    # two discovery folders stand for two hosts; only the peer exchange joins them (over tcp on 127.0.0.1)
    port_a, port_b = _free_port(), _free_port()
    folder_a = tempfile.mkdtemp(prefix="dga", dir="/tmp")
    folder_b = tempfile.mkdtemp(prefix="dgb", dir="/tmp")
    # the two "hosts" share one key pair (as when the curve folder is copied): a peer without a listed key uses it
    keys = tempfile.mkdtemp(prefix="dgk", dir="/tmp")
    public, secret = zmq.auth.create_certificates(keys, "site")
    authorized = f"{keys}/authorized"
    os.mkdir(authorized)
    shutil.copy(public, authorized)
    curve = {"DPTPU_CURVE_SECRET_KEY": secret, "DPTPU_CURVE_AUTHORIZED_KEYS": authorized}
    host_a = {"DPTPU_DISCOVERY_DIR": folder_a, "DPTPU_TRANSPORT": "tcp", "DPTPU_DISCOVERY_PORT": str(port_a),
              "DPTPU_PEERS": f"127.0.0.1:{port_b}", **curve}
    host_b = {"DPTPU_DISCOVERY_DIR": folder_b, "DPTPU_TRANSPORT": "tcp", "DPTPU_DISCOVERY_PORT": str(port_b),
              "DPTPU_PEERS": f"127.0.0.1:{port_a}", **curve}
    try:
        listener = spawn("listener", "--count", "3", "--timeout", "10", env=host_b)
        listener.wait_event("ready")
        talker = spawn("talker", "--count", "3", "--wait-subs", "1", "--linger", "1", env=host_a)
        assert talker.wait_event("published", timeout=10)["count"] == 3
        assert listener.wait_event("done")["received"] == ["0", "1", "2"]
        listener.wait()
        talker.wait()
    finally:
        shutil.rmtree(folder_a, ignore_errors=True)
        shutil.rmtree(folder_b, ignore_errors=True)
        shutil.rmtree(keys, ignore_errors=True)


def test_tcp_is_curve_by_default_with_keys_made_private_in_the_discovery_folder(spawn, domain_dir):
    # issue 19: tcp without keys let another local user read clouds, start scans and set parameters
    env = {"DPTPU_TRANSPORT": "tcp"}
    listener = spawn("listener", "--count", "3", env=env)
    listener.wait_event("ready")
    secret = domain_dir / "curve" / "participant.key_secret"
    assert secret.is_file() and (secret.stat().st_mode & 0o777) == 0o600
    assert (secret.parent.stat().st_mode & 0o777) == 0o700
    talker = spawn("talker", "--count", "400", "--period", "0.02", "--wait-subs", "1", "--linger", "0", env=env)
    talker.wait_event("ready")
    assert listener.wait_event("done")["received"] == ["0", "1", "2"]
    # a stranger who learnt the talker's tcp endpoint (a copy of the announcements, as a port scan would give) but
    # has no keys: the CurveZMQ handshake fails, it gets nothing
    stranger_dir = tempfile.mkdtemp(prefix="dgs", dir="/tmp")
    try:
        copy = os.path.join(stranger_dir, domain_dir.name)
        os.mkdir(copy, 0o700)
        for announcement in domain_dir.glob("n-*.json"):  # the talker's (the listener may be gone)
            with contextlib.suppress(FileNotFoundError):
                shutil.copy(announcement, copy)
        stranger = spawn("listener", "--name", "stranger", "--timeout", "2.0",
                         env={**env, "DPTPU_CURVE": "off", "DPTPU_DISCOVERY_DIR": stranger_dir})
        done = stranger.wait_event("done", timeout=20)
        assert stranger.wait_for_stderr("without CurveZMQ (DPTPU_CURVE=off)", timeout=5.0)
        assert done["received"] == [] and talker.proc.poll() is None
    finally:
        shutil.rmtree(stranger_dir, ignore_errors=True)
