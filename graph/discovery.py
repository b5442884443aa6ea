"""Daemonless discovery: every node announces itself in a file; every process watches the folder.

Each node writes one JSON announcement (format ``dptpu-graph/1``) into its domain's folder::

    $DPTPU_DISCOVERY_DIR/domain-<id>/     (default base: $XDG_RUNTIME_DIR/dptpu, else /tmp/dptpu-<uid>)
        n-<pid>-<node gid>.json           one per node: name, namespace, pid, host, publishers
                                          (topic, type, endpoints, qos, counts), subscriptions,
                                          services, clients, start time
        ep/<id>                           the Unix socket files of ipc endpoints

The file is written atomically (temporary file + rename), rewritten when the node's entities
change and at most once a second when its counters change, and removed on clean shutdown. A
background thread in each process re-reads the folder every :data:`SCAN_INTERVAL_S` (only files whose
size, time or inode changed are parsed). An announcement whose process is gone (no such pid, or a pid
reused by a process that started later) is stale: it is ignored at once and deleted, with its socket
files, within :data:`LIVENESS_INTERVAL_S`. The domain folder is created with mode 0700 and must belong
to the user, so other users can neither read the graph nor connect to its ipc endpoints.

:func:`get_graph` reads a domain's folder once and returns a :class:`GraphSnapshot` (nodes, topics with
types and publisher/subscription counts, services); the introspection CLI uses it.
"""

from __future__ import annotations

import json
import os
import socket as _socket
import stat
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .processes import process_alive, process_start_ticks
from .qos import QoSProfile
from .transport import remove_ipc_file

__all__ = [
    "FORMAT", "SCAN_INTERVAL_S", "LIVENESS_INTERVAL_S", "DOMAIN_ID_MAX",
    "resolve_domain_id", "base_directory", "domain_directory", "ensure_private_directory",
    "host_identity", "process_start_ticks", "announcement_file_name", "write_announcement", "remove_announcement",
    "read_announcement", "entry_is_alive", "DirectoryScanner",
    "EndpointInfo", "NodeInfo", "TopicInfo", "ServiceInfo", "GraphSnapshot", "get_graph", "snapshot_from_entries",
]

FORMAT = "dptpu-graph/1"
#: Seconds between two reads of the discovery folder.
SCAN_INTERVAL_S = 0.1
#: Seconds between two liveness checks of the processes behind the announcements.
LIVENESS_INTERVAL_S = 1.0
#: Largest domain id (ROS 2's range is 0..232).
DOMAIN_ID_MAX = 232
_PREFIX = "n-"
_SUFFIX = ".json"


# --------------------------------------------------------------------------------------------------
# Where
# --------------------------------------------------------------------------------------------------

def resolve_domain_id(domain_id=None, env=None) -> int:
    """``domain_id``, else ``$DPTPU_DOMAIN_ID``, else ``$ROS_DOMAIN_ID``, else 0; checked to lie in 0..232."""
    env = os.environ if env is None else env
    source = "domain_id"
    if domain_id is None:
        for name in ("DPTPU_DOMAIN_ID", "ROS_DOMAIN_ID"):
            text = env.get(name, "").strip()
            if text:
                source = f"${name}"
                try:
                    domain_id = int(text)
                except ValueError:
                    raise ValueError(f"{source} must be an integer in 0..{DOMAIN_ID_MAX}; got {text!r}") from None
                break
        else:
            domain_id = 0
    if isinstance(domain_id, bool) or not isinstance(domain_id, int) or not 0 <= domain_id <= DOMAIN_ID_MAX:
        raise ValueError(f"{source} must be an integer in 0..{DOMAIN_ID_MAX}; got {domain_id!r}")
    return domain_id


def base_directory(env=None) -> Path:
    """``$DPTPU_DISCOVERY_DIR``, else ``$XDG_RUNTIME_DIR/dptpu``, else ``<tmp>/dptpu-<uid>``."""
    env = os.environ if env is None else env
    explicit = env.get("DPTPU_DISCOVERY_DIR", "").strip()
    if explicit:
        return Path(explicit)
    runtime_dir = env.get("XDG_RUNTIME_DIR", "").strip()
    if runtime_dir and os.path.isdir(runtime_dir) and os.access(runtime_dir, os.W_OK):
        return Path(runtime_dir) / "dptpu"
    return Path(tempfile.gettempdir()) / f"dptpu-{os.getuid()}"


def domain_directory(domain_id=None, *, base=None) -> Path:
    """The announcement folder of a domain (not created)."""
    return Path(base if base is not None else base_directory()) / f"domain-{resolve_domain_id(domain_id)}"


def ensure_private_directory(path: Path) -> Path:
    """Create ``path`` (mode 0700) if needed, check it belongs to this user and make it private (0700).

    An existing folder of the user that others could only read or enter (e.g. 0755 from a ``mkdir``) is made 0700:
    the announcements name every endpoint and the ipc socket files are inside.

    Raises
    ------
    PermissionError
        When the folder belongs to another user or others may write to it.
    """
    path = Path(path)
    path.mkdir(mode=0o700, parents=True, exist_ok=True)
    info = path.stat()
    if info.st_uid != os.getuid():
        raise PermissionError(f"discovery folder {str(path)!r} belongs to uid {info.st_uid}, not to this user "
                              f"({os.getuid()}); set DPTPU_DISCOVERY_DIR to a folder of yours")
    if info.st_mode & (stat.S_IWGRP | stat.S_IWOTH):  # others may have put or swapped files in it already
        raise PermissionError(f"discovery folder {str(path)!r} is writable by others (mode "
                              f"{oct(info.st_mode & 0o777)}); chmod 700 it")
    if info.st_mode & (stat.S_IRWXG | stat.S_IRWXO):
        os.chmod(path, 0o700)
    return path


# --------------------------------------------------------------------------------------------------
# Who
# --------------------------------------------------------------------------------------------------

def host_identity() -> tuple[str, str]:
    """``(host name, boot id)``: two announcements are on the same machine when both match."""
    try:
        boot_id = Path("/proc/sys/kernel/random/boot_id").read_text().strip()
    except OSError:
        boot_id = ""
    return _socket.gethostname(), boot_id


def entry_is_alive(entry: dict, host: str, boot_id: str) -> bool:
    """Whether an announcement is current: not expired (peer entries) and, for this host, its process runs."""
    expires = entry.get("expires")
    if expires is not None and (not isinstance(expires, (int, float)) or expires < time.time()):
        return False
    if entry.get("host") != host or entry.get("boot_id") != boot_id:
        return True
    pid = entry.get("pid")
    if not isinstance(pid, int) or not process_alive(pid):
        return False
    announced = entry.get("pid_start")
    if announced is None:
        return True
    current = process_start_ticks(pid)
    return current is None or current == announced


# --------------------------------------------------------------------------------------------------
# Files
# --------------------------------------------------------------------------------------------------

def announcement_file_name(pid: int, node_gid: str) -> str:
    return f"{_PREFIX}{pid}-{node_gid}{_SUFFIX}"


def write_announcement(directory: Path, file_name: str, entry: dict) -> None:
    """Write ``entry`` as JSON to ``directory/file_name`` atomically (readers never see half a file)."""
    final = Path(directory) / file_name
    temporary = Path(directory) / f".{file_name}.{os.getpid()}.tmp"
    # json.dumps, not json.dump: dump always runs the pure-Python encoder, whose nested functions make reference
    # cycles left for the garbage collector on every write (a node rewrites its entry about once a second; with
    # the nodes' gc thresholds they piled up for thousands of scans: issue 19's soak); dumps runs the C encoder
    text = json.dumps(entry, separators=(",", ":"))
    with open(temporary, "w", encoding="utf-8") as handle:
        handle.write(text)
    os.replace(temporary, final)


def remove_announcement(directory: Path, file_name: str) -> None:
    try:
        os.unlink(Path(directory) / file_name)
    except OSError:
        pass


def read_announcement(path: Path) -> dict | None:
    """The announcement in ``path``, or None when it is unreadable, not JSON or not ``dptpu-graph/1``."""
    try:
        with open(path, encoding="utf-8") as handle:
            entry = json.load(handle)
    except (OSError, ValueError):
        return None
    if not isinstance(entry, dict) or entry.get("format") != FORMAT:
        return None
    for key in ("publishers", "subscriptions", "services", "clients"):
        if not isinstance(entry.get(key, []), list):
            return None
    return entry


def _without_counters(entry) -> dict:
    """An announcement less what changes while nothing but traffic does: its ``updated`` time and the
    ``stats`` of its publishers and subscriptions (what matching never reads)."""
    view = {key: value for key, value in entry.items() if key != "updated"}
    for key in ("publishers", "subscriptions"):
        items = view.get(key)
        if isinstance(items, list):
            view[key] = [{k: v for k, v in item.items() if k != "stats"} if isinstance(item, dict) else item
                         for item in items]
    return view


class DirectoryScanner:
    """Incremental reader of one discovery folder (used by the runtime's I/O thread).

    ``scan()`` re-reads changed files and drops vanished ones; ``entries`` is the current list of live
    announcements (a new list object after every change, so readers in other threads may keep it).
    Files named in ``own_files`` (this process's) are skipped: the runtime knows its own nodes.

    ``topology_changed`` (after a ``scan()`` that returned True) says whether more than counters changed: a node
    rewrites its announcement about once a second while its counters move (``stats``, ``updated``), and the
    runtime then refreshes its graph snapshot without matching its sockets again. A file rewritten by the process
    already found alive is not asked about again: the liveness pass (every :data:`LIVENESS_INTERVAL_S`) is.
    """

    def __init__(self, directory: Path, *, host: str, boot_id: str, clean_stale: bool = True):
        self.directory = Path(directory)
        self.host, self.boot_id = host, boot_id
        self.clean_stale = clean_stale
        self.own_files: set[str] = set()
        self._cache: dict[str, tuple[tuple, dict | None]] = {}
        self._dead: set[str] = set()
        self.entries: list[dict] = []
        self.topology_changed = False
        self._next_liveness = 0.0

    def scan(self, now: float | None = None) -> bool:
        """Re-read the folder; True when the set of live announcements or their contents changed
        (``topology_changed``: more than their counters)."""
        now = time.monotonic() if now is None else now
        changed = topology = False
        seen = set()
        try:
            listing = list(os.scandir(self.directory))
        except OSError:
            listing = []
        for item in listing:
            name = item.name
            if not (name.startswith(_PREFIX) and name.endswith(_SUFFIX)) or name in self.own_files:
                continue
            try:
                info = item.stat()
            except OSError:
                continue
            seen.add(name)
            key = (info.st_mtime_ns, info.st_size, info.st_ino)
            cached = self._cache.get(name)
            if cached is not None and cached[0] == key:
                continue
            entry = read_announcement(Path(item.path))
            before = cached[1] if cached is not None else None
            same_process = (entry is not None and before is not None and entry.get("pid") == before.get("pid")
                            and entry.get("pid_start") == before.get("pid_start") and "expires" not in entry)
            if entry is not None and not same_process and not entry_is_alive(entry, self.host, self.boot_id):
                self._dead.add(name)
                entry = None
            else:
                self._dead.discard(name)
            self._cache[name] = (key, entry)
            changed = True
            if not (same_process and _without_counters(entry) == _without_counters(before)):
                topology = True
        for name in list(self._cache):
            if name not in seen:
                del self._cache[name]
                self._dead.discard(name)
                changed = topology = True
        if now >= self._next_liveness:
            self._next_liveness = now + LIVENESS_INTERVAL_S
            if self._check_liveness():
                changed = topology = True
        if changed:
            self.entries = [entry for _, entry in self._cache.values() if entry is not None]
        self.topology_changed = topology
        return changed

    def _check_liveness(self) -> bool:
        changed = False
        for name, (key, entry) in list(self._cache.items()):
            if entry is not None and not entry_is_alive(entry, self.host, self.boot_id):
                self._cache[name] = (key, None)
                self._dead.add(name)
                changed = True
        if self.clean_stale:
            for name in list(self._dead):
                self._remove_stale(name)
        return changed

    def _remove_stale(self, name: str) -> None:
        path = self.directory / name
        entry = read_announcement(path)
        if entry is not None and entry_is_alive(entry, self.host, self.boot_id):
            return  # rewritten by a live process meanwhile
        if entry is not None:
            for endpoint in _all_endpoints(entry):
                remove_ipc_file(endpoint)
        try:
            os.unlink(path)
        except OSError:
            pass
        self._dead.discard(name)
        self._cache.pop(name, None)


def _all_endpoints(entry: dict) -> list[str]:
    endpoints = list(entry.get("service_endpoints") or [])
    for publisher in entry.get("publishers", []):
        endpoints.extend(publisher.get("endpoints") or [])
    return [e for e in endpoints if isinstance(e, str)]


# --------------------------------------------------------------------------------------------------
# Snapshot for introspection
# --------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class EndpointInfo:
    """One publisher or subscription as announced.

    Attributes
    ----------
    node : str
        Fully qualified name of its node.
    topic, type : str
    qos : QoSProfile or None
    gid : str
    endpoints : tuple of str
        Where a publisher can be reached (empty for subscriptions).
    stats : dict
        Counters, e.g. ``published_count`` or ``received_count``, ``dropped_count``,
        ``lost_count``, ``malformed_count`` (refreshed about once a second).
    """

    node: str
    topic: str
    type: str
    qos: QoSProfile | None
    gid: str
    endpoints: tuple = ()
    stats: dict = field(default_factory=dict)


@dataclass(frozen=True)
class NodeInfo:
    name: str
    namespace: str
    fully_qualified_name: str
    pid: int
    host: str
    start_time: float
    publishers: tuple
    subscriptions: tuple
    services: tuple  # ((name, type), ...)
    clients: tuple


@dataclass(frozen=True)
class TopicInfo:
    name: str
    types: tuple
    publishers: tuple
    subscriptions: tuple

    @property
    def publisher_count(self) -> int:
        return len(self.publishers)

    @property
    def subscription_count(self) -> int:
        return len(self.subscriptions)


@dataclass(frozen=True)
class ServiceInfo:
    name: str
    types: tuple
    servers: tuple  # node names
    clients: tuple


@dataclass(frozen=True)
class GraphSnapshot:
    """The graph of one domain at one moment: ``nodes``, ``topics`` and ``services`` by name."""

    domain_id: int | None
    nodes: tuple
    topics: dict
    services: dict

    def to_dict(self) -> dict:
        """Plain JSON-ready form."""
        def endpoint(e: EndpointInfo) -> dict:
            return {"node": e.node, "topic": e.topic, "type": e.type, "qos": e.qos.to_dict() if e.qos else None,
                    "gid": e.gid, "endpoints": list(e.endpoints), "stats": dict(e.stats)}

        return {
            "domain_id": self.domain_id,
            "nodes": [{"name": n.name, "namespace": n.namespace, "fully_qualified_name": n.fully_qualified_name,
                       "pid": n.pid, "host": n.host, "start_time": n.start_time,
                       "publishers": [endpoint(e) for e in n.publishers],
                       "subscriptions": [endpoint(e) for e in n.subscriptions],
                       "services": [list(s) for s in n.services], "clients": [list(c) for c in n.clients]}
                      for n in self.nodes],
            "topics": {name: {"types": list(t.types), "publisher_count": t.publisher_count,
                              "subscription_count": t.subscription_count,
                              "publishers": [endpoint(e) for e in t.publishers],
                              "subscriptions": [endpoint(e) for e in t.subscriptions]}
                       for name, t in self.topics.items()},
            "services": {name: {"types": list(s.types), "servers": list(s.servers), "clients": list(s.clients)}
                         for name, s in self.services.items()},
        }


def _qos_or_none(data) -> QoSProfile | None:
    try:
        return QoSProfile.from_dict(data)
    except Exception:  # noqa: BLE001 -- a foreign announcement may hold anything
        return None


def _endpoint_info(node: str, item: dict) -> EndpointInfo | None:
    if not isinstance(item, dict) or not isinstance(item.get("topic"), str):
        return None
    return EndpointInfo(node=node, topic=item["topic"], type=str(item.get("type", "")),
                        qos=_qos_or_none(item.get("qos")), gid=str(item.get("gid", "")),
                        endpoints=tuple(item.get("endpoints") or ()), stats=dict(item.get("stats") or {}))


def snapshot_from_entries(entries, domain_id=None) -> GraphSnapshot:
    """Build a :class:`GraphSnapshot` from announcement dicts."""
    nodes: list[NodeInfo] = []
    topics: dict[str, dict[str, Any]] = {}  # name -> {"types": set, "publishers": [...], "subscriptions": [...]}
    services: dict[str, dict[str, Any]] = {}  # name -> {"types": set, "servers": [fqn, ...], "clients": [...]}
    for entry in sorted(entries, key=lambda e: (str(e.get("fqn")), str(e.get("gid")))):
        fqn = str(entry.get("fqn", ""))
        # tuple([...]), not tuple(generator): a tuple built from a generator is resized into place, never taken from
        # CPython's free list, but given to it when freed; a snapshot a second filled the lists (2,000 tuples of
        # each size) for half an hour: issue 19's soak
        pubs = tuple([e for e in (_endpoint_info(fqn, p) for p in entry.get("publishers", [])) if e])
        subs = tuple([e for e in (_endpoint_info(fqn, s) for s in entry.get("subscriptions", [])) if e])
        srvs = tuple([(str(s.get("name")), str(s.get("type"))) for s in entry.get("services", [])
                      if isinstance(s, dict)])
        clis = tuple([(str(c.get("name")), str(c.get("type"))) for c in entry.get("clients", [])
                      if isinstance(c, dict)])
        nodes.append(NodeInfo(name=str(entry.get("name", "")), namespace=str(entry.get("namespace", "/")),
                              fully_qualified_name=fqn, pid=int(entry.get("pid", 0) or 0),
                              host=str(entry.get("host", "")), start_time=float(entry.get("start_time", 0.0) or 0.0),
                              publishers=pubs, subscriptions=subs, services=srvs, clients=clis))
        for kind, endpoints in (("publishers", pubs), ("subscriptions", subs)):
            for item in endpoints:
                topics.setdefault(item.topic, {"types": set(), "publishers": [], "subscriptions": []})
                if item.type != "*":  # a raw subscription to any type
                    topics[item.topic]["types"].add(item.type)
                topics[item.topic][kind].append(item)
        for kind, names in (("servers", srvs), ("clients", clis)):
            for name, type_name in names:
                services.setdefault(name, {"types": set(), "servers": [], "clients": []})
                services[name]["types"].add(type_name)
                services[name][kind].append(fqn)
    return GraphSnapshot(
        domain_id=domain_id, nodes=tuple(nodes),
        topics={name: TopicInfo(name, tuple(sorted(t["types"])), tuple(t["publishers"]), tuple(t["subscriptions"]))
                for name, t in sorted(topics.items())},
        services={name: ServiceInfo(name, tuple(sorted(s["types"])), tuple(s["servers"]), tuple(s["clients"]))
                  for name, s in sorted(services.items())})


def get_graph(domain_id=None, *, directory=None) -> GraphSnapshot:
    """Read a domain's announcements once and return the graph (stale ones are left out, not deleted).

    Parameters
    ----------
    domain_id : int, optional
        Domain (default: ``$DPTPU_DOMAIN_ID``, ``$ROS_DOMAIN_ID``, 0).
    directory : path, optional
        The domain's folder itself (default: :func:`domain_directory`).
    """
    domain = resolve_domain_id(domain_id) if directory is None or domain_id is not None else None
    folder = Path(directory) if directory is not None else domain_directory(domain)
    host, boot_id = host_identity()
    scanner = DirectoryScanner(folder, host=host, boot_id=boot_id, clean_stale=False)
    scanner.scan()
    return snapshot_from_entries(scanner.entries, domain)
