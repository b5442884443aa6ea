"""Large messages between processes of one host through shared memory: the wire form and the reading side.

A publisher whose subscribers are all on its own host, as the same user, writes the arrays of a large message
(at least ``DPTPU_SHM_MIN_BYTES`` together) into a segment of its pool (:mod:`.segment_pool`) and sends, through
ZeroMQ as before, only the topic, the header and a small descriptor::

    [SHM topic, header, descriptor]  +  [envelope]

The subscriber maps the segment read-only and hands the decoder views of it: the arrays of the message it gets
are read-only numpy views of the publisher's segment (no copy between the processes at all).

Why memfd segments opened through ``/proc/<pid>/fd`` (not ``multiprocessing.shared_memory`` or files in
``/dev/shm``): a segment has no name in any file system, so nothing is left behind when a publisher or a
subscriber is killed (``kill -9``): the kernel frees a segment when the last process that has it open or mapped
goes; a named segment in ``/dev/shm`` outlives a crashed publisher until someone removes it. And the kernel
lets only processes of the publisher's own user (who may read its ``/proc/<pid>/fd``) open a segment at all; the
segment's mode is 0600 besides.

Safety, per segment (a header of 64 bytes, then the arrays at 64-byte aligned offsets):

- **Locks**: the publisher writes a segment only holding an exclusive ``flock``; a subscriber holds a shared
  ``flock`` from the moment it takes the message off its socket until the last array of the message is garbage
  (a weak reference's callback on the arrays' common base). So a segment that a subscriber still reads is never
  rewritten; the kernel drops the locks of a killed process.
- **Generation**: each write increments the segment's generation, written in its header and in the descriptor.
  A subscriber that comes to a descriptor after its segment was written again (its generation moved on) refuses
  it: the message is counted as lost, never read from the newer contents.
- **Pickups and leases**: a subscriber counts itself in the segment's header when it takes the shared lock;
  the publisher reuses a segment once every subscriber it sent the descriptor to has picked it up and let go,
  or, for a descriptor that never arrives (dropped at a full pipe, a subscriber gone), once the lease
  (``DPTPU_SHM_LEASE_S``) since its publication has passed. A subscriber also counts each message it lets go
  (before it lets go of the lock): while a segment's pickups outnumber its let-gos, and its lease has not passed,
  the publisher does not even try its lock (a reader holding a scan's frames costs the writer no system call a
  frame); the lock alone decides whether a segment is free (a killed reader never counts its let-go: after the
  lease its segment is judged by the lock, which the kernel dropped).
- **Fallback**: a publisher with a subscriber that cannot map its segments (on another host, over tcp, another
  user, ``DPTPU_SHM=off``; logged once, naming it: :func:`unmappable_subscribers`), a small message, a
  TRANSIENT_LOCAL publisher (its history is replayed), a full pool (``DPTPU_SHM_POOL_MB``; logged once), a process
  that is not dumpable or holds :data:`FD_SHARE` of its descriptor limit, or a segment the kernel refuses
  (:mod:`.segment_pool`) sends the whole message through ZeroMQ, as without shared memory. A subscription whose
  process holds :data:`FD_GIVE_UP_SHARE` of its descriptor limit asks for no more descriptors
  (:func:`short_of_descriptors`). Where the boot id cannot be read, shared memory is off (:func:`available`).
- **Hardening**: segments are sealed against resizing (a subscriber maps no other file: nothing can shrink one under
  a reader, which would kill it with SIGBUS); a descriptor is opened only if it names a regular file.

Which subscribers can map: a subscription whose process may use shared memory subscribes, beside its topic, to
``SHM topic`` = ``"\\0shm:" + host key + "\\0" + topic``, where the host key names this kernel, PID namespace and
user (:func:`host_key`). The publisher's XPUB socket sees every subscription; it counts the subscribers of its
topic and, among them, those with its own host key, and sends descriptors only when the two counts agree.

Configuration (environment variables, read when a context starts its runtime):

==========================  ====================================================================================
``DPTPU_SHM``               ``auto`` (default): shared memory between processes of one host on ipc; ``off``
``DPTPU_SHM_MIN_BYTES``     smallest total of a message's arrays sent through shared memory (default 65536)
``DPTPU_SHM_POOL_MB``       most memory of one publisher's segments, MiB (default 256); beyond it, ZeroMQ
``DPTPU_SHM_LEASE_S``       seconds after which a segment whose descriptor was not picked up is reused (1.0)
``DPTPU_SHM_IDLE_S``        seconds after its last write when a publisher closes a free segment (default
                            :data:`.segment_pool.IDLE_S`)
==========================  ====================================================================================
"""

from __future__ import annotations

import errno
import fcntl
import hashlib
import mmap
import os
import resource
import stat
import struct
import threading
import time
import weakref
from dataclasses import dataclass

import numpy as np

from .processes import process_alive

__all__ = [
    "SharedMemoryConfig", "SharedMemoryError", "StaleSegmentError", "host_key", "shm_topic",
    "HEADER_BYTES", "SEGMENT_MAGIC", "pack_descriptor", "unpack_descriptor", "Descriptor", "read_message",
    "sweep_mappings", "mapped_segment_count", "ALIGNMENT", "RELEASES_OFFSET", "SEALS", "descriptor_room",
    "short_of_descriptors", "FD_SHARE", "FD_GIVE_UP_SHARE", "OTHER_DESCRIPTORS", "unmappable_subscribers",
]

#: Bytes of a segment's header: magic (8), token (16), generation (u64), pickups (u64), size (u64), let-gos (u64),
#: padding.
HEADER_BYTES = 64
#: Alignment of every array in a segment, bytes (a cache line; numpy's SIMD loops like it).
ALIGNMENT = 64
SEGMENT_MAGIC = b"DPTPUSHM"
_HEADER = struct.Struct("<8s16sQQQ")
GENERATION_OFFSET = 24
PICKUPS_OFFSET = 32
#: Offset of the let-go counter (u64): each reader adds one when it lets a message of the segment go, before its
#: lock; the publisher skips, without a system call, a segment whose pickups outnumber its let-gos (a hint only).
RELEASES_OFFSET = 48
_COUNTER = struct.Struct("<Q")
#: The seals of every segment (``F_ADD_SEALS``): its size can never change, so no process can shrink it under a
#: mapping (a read past the end of a file kills the reader with SIGBUS); a subscriber maps only segments that have
#: them.
SEALS = fcntl.F_SEAL_SHRINK | fcntl.F_SEAL_GROW | fcntl.F_SEAL_SEAL

_DESCRIPTOR = struct.Struct("<4sBBHIIQ16sQQ")
_ENTRY = struct.Struct("<QQ")
_DESCRIPTOR_MAGIC = b"DPSM"
_DESCRIPTOR_VERSION = 1
#: Most arrays one descriptor names (the codec's own limit on array frames is lower).
MAX_ARRAYS = 1024
#: Seconds an unused mapping of a segment is kept by a subscriber's process (a publisher may write it again).
MAPPING_IDLE_S = 5.0
#: Share of the process's soft file-descriptor limit (``ulimit -n``) beyond which its publishers make no new segment
#: (each costs two descriptors: the memfd and the duplicate Python's ``mmap`` keeps; so does each mapped one).
FD_SHARE = 0.5
#: Share beyond which a subscription of this process gives up shared memory (:func:`short_of_descriptors`): the rest
#: maps the descriptors already on their way, and leaves the process its sockets and files.
FD_GIVE_UP_SHARE = 0.75


#: Descriptors a process is taken to hold besides its segments (sockets, files) when judging, without counting them,
#: that it is far from its limit.
OTHER_DESCRIPTORS = 256
#: Segments of this process's own pools (:mod:`.segment_pool` keeps the count): two descriptors each.
own_segments = [0]


def descriptor_room(share: float = FD_SHARE) -> tuple[int, int]:
    """``(open, allowed)``: the file descriptors this process has open, and ``share`` of its soft limit.

    Far from the limit (two descriptors a segment of its own or mapped, plus :data:`OTHER_DESCRIPTORS`, within
    ``allowed``) ``open`` is that estimate: counting them (``/proc/self/fd``) costs ~0.5 ms at 250 descriptors.
    """
    soft = resource.getrlimit(resource.RLIMIT_NOFILE)[0]
    allowed = 1 << 30 if soft == resource.RLIM_INFINITY else int(soft * share)
    estimate = 2 * (len(_mappings) + own_segments[0]) + OTHER_DESCRIPTORS
    if estimate <= allowed:
        return estimate, allowed
    try:
        return len(os.listdir("/proc/self/fd")), allowed
    except OSError:
        return 0, allowed


class SharedMemoryError(ValueError):
    """A descriptor that cannot be read: malformed, or its segment is gone or is not what it claims."""


class StaleSegmentError(SharedMemoryError):
    """The descriptor's segment was written again (or is being written) before this subscriber picked it up."""


@dataclass(frozen=True)
class SharedMemoryConfig:
    """How this process uses shared memory (``DPTPU_SHM*``, see the module docstring).

    Attributes
    ----------
    min_bytes : int
        Smallest total of a message's array bytes sent through shared memory.
    pool_bytes : int
        Most bytes of one publisher's segments together.
    lease_s : float
        Seconds after a publication when its segment is reused even if not every subscriber picked it up.
    key : bytes
        This process's host key (:func:`host_key`).
    idle_s : float or None
        Seconds after its last write when a free segment is closed; None: :data:`.segment_pool.IDLE_S`.
    """

    min_bytes: int = 65536
    pool_bytes: int = 256 << 20
    lease_s: float = 1.0
    key: bytes = b""
    idle_s: float | None = None

    @classmethod
    def from_environment(cls, env=None) -> SharedMemoryConfig | None:
        """The configuration, or None when shared memory is off (``DPTPU_SHM=off``) or unavailable here.

        Raises
        ------
        ValueError
            A variable that is not what the module docstring says, naming it and the value.
        """
        env = os.environ if env is None else env
        mode = env.get("DPTPU_SHM", "auto").strip().lower() or "auto"
        if mode not in ("auto", "off"):
            raise ValueError(f"DPTPU_SHM must be 'auto' or 'off'; got {mode!r}")
        min_bytes = _number(env, "DPTPU_SHM_MIN_BYTES", 65536, int, low=1)
        pool_mb = _number(env, "DPTPU_SHM_POOL_MB", 256, float, low=1.0)
        lease_s = _number(env, "DPTPU_SHM_LEASE_S", 1.0, float, low=0.001)
        idle_s = _number(env, "DPTPU_SHM_IDLE_S", None, float, low=0.001)
        if mode == "off" or not available():
            return None
        return cls(int(min_bytes), int(pool_mb * (1 << 20)), float(lease_s), host_key(),
                   None if idle_s is None else float(idle_s))


def _number(env, name: str, default, kind, *, low):
    text = env.get(name, "").strip()
    if not text:
        return default
    try:
        value = kind(text)
    except ValueError:
        value = None
    if value is None or not value >= low or value != value or value == float("inf"):
        raise ValueError(f"{name} must be a {kind.__name__} >= {low}; got {text!r}")
    return value


def available() -> bool:
    """True when this system has what the shared-memory path needs (Linux: memfd, ``/proc/<pid>/fd``) and its
    kernel can be told from another host's (a boot id): without one, processes of two hosts that see the same
    first PID namespace (its inode is the same on every Linux) would share a host key, and a subscriber on the other
    host would get descriptors it cannot map."""
    return hasattr(os, "memfd_create") and os.path.isdir(f"/proc/{os.getpid()}/fd") and bool(_boot_id())


def _boot_id() -> bytes:
    """This kernel's boot id (random at each boot), or b"" where it cannot be read (a sandbox that hides it)."""
    try:
        with open("/proc/sys/kernel/random/boot_id", "rb") as file:
            return file.read().strip()
    except OSError:
        return b""


_HOST_KEY: bytes | None = None


def host_key() -> bytes:
    """16 hex bytes naming this kernel (its boot id), PID namespace and user: who can open whose segments.

    Two processes with the same key can open each other's segments through ``/proc/<pid>/fd`` (the kernel lets
    a process open the descriptors of processes of its own user in its PID namespace); any other pair cannot.
    """
    global _HOST_KEY
    if _HOST_KEY is None:
        boot = _boot_id() or b"no-boot-id"  # then shared memory is off (available)
        try:
            namespace = os.stat("/proc/self/ns/pid").st_ino
        except OSError:
            namespace = 0
        digest = hashlib.blake2b(b"%s:%d:%d" % (boot, namespace, os.getuid()), digest_size=8).hexdigest()
        _HOST_KEY = digest.encode("ascii")
    return _HOST_KEY


def shm_topic(topic: bytes, key: bytes) -> bytes:
    """The subscription (and first frame) of ``topic``'s shared-memory descriptors for host key ``key``.

    It starts with a NUL byte, so no topic name is a prefix of it and plain subscribers never receive it.
    """
    return b"\0shm:" + key + b"\0" + topic


# --------------------------------------------------------------------------------------------------
# Descriptor
# --------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Descriptor:
    """Where a message's arrays are: the publisher's process and descriptor, the segment's identity and
    generation, and each array's ``(offset, nbytes)`` in the segment."""

    pid: int
    fd: int
    inode: int
    token: bytes
    generation: int
    size: int
    entries: tuple


def pack_descriptor(pid: int, fd: int, inode: int, token: bytes, generation: int, size: int, entries) -> bytes:
    """The descriptor frame (40 bytes and 16 per array)."""
    return b"".join([_DESCRIPTOR.pack(_DESCRIPTOR_MAGIC, _DESCRIPTOR_VERSION, 0, len(entries), pid, fd, inode, token,
                                      generation, size),
                     *(_ENTRY.pack(offset, nbytes) for offset, nbytes in entries)])


def unpack_descriptor(frame) -> Descriptor:
    """Parse a descriptor frame; :class:`SharedMemoryError` naming what is wrong."""
    data = memoryview(getattr(frame, "buffer", frame))
    if data.nbytes < _DESCRIPTOR.size:
        raise SharedMemoryError(f"shared-memory descriptor of {data.nbytes} bytes; expected at least "
                                f"{_DESCRIPTOR.size}")
    magic, version, _reserved, count, pid, fd, inode, token, generation, size = _DESCRIPTOR.unpack_from(data)
    if magic != _DESCRIPTOR_MAGIC or version != _DESCRIPTOR_VERSION:
        raise SharedMemoryError(f"shared-memory descriptor has magic {magic!r} version {version}; expected "
                                f"{_DESCRIPTOR_MAGIC!r} version {_DESCRIPTOR_VERSION}")
    if data.nbytes != _DESCRIPTOR.size + count * _ENTRY.size or count > MAX_ARRAYS:
        raise SharedMemoryError(f"shared-memory descriptor of {data.nbytes} bytes names {count} arrays")
    entries = tuple(_ENTRY.iter_unpack(data[_DESCRIPTOR.size:]))
    for offset, nbytes in entries:
        if offset < HEADER_BYTES or offset + nbytes > size:
            raise SharedMemoryError(f"shared-memory descriptor names bytes {offset}..{offset + nbytes} of a "
                                    f"segment of {size}")
    return Descriptor(pid, fd, inode, token, generation, size, entries)


# --------------------------------------------------------------------------------------------------
# Reading side: one table of mapped segments per process
# --------------------------------------------------------------------------------------------------

class _Mapping:
    """One segment mapped read-only by this process; ``holders`` messages of it are alive here."""

    __slots__ = ("fd", "view", "size", "holders", "generation", "last_used", "pid", "__weakref__")

    def __init__(self, fd: int, view: mmap.mmap, size: int, pid: int):
        self.fd = fd
        self.view = view
        self.size = size
        self.pid = pid
        self.holders = 0
        self.generation = -1
        self.last_used = time.monotonic()

    def close(self) -> bool:
        try:
            self.view.close()
        except BufferError:
            return False  # an array of it is still alive (its finalizer has not run yet): later
        os.close(self.fd)
        return True


_lock = threading.RLock()  # re-entrant: a finalizer (_release) may run inside _acquire, on a garbage collection
_mappings: dict[tuple, _Mapping] = {}
_next_sweep = [0.0]
_short = [False]  # whether the last new mapping left this process above FD_GIVE_UP_SHARE of its descriptors


def short_of_descriptors() -> bool:
    """Whether this process, when it last mapped a new segment, held more than :data:`FD_GIVE_UP_SHARE` of its
    file-descriptor limit: its subscriptions then take everything through ZeroMQ (a subscriber that holds many
    messages, e.g. a recorder behind its stream, would otherwise run out and lose the messages it cannot map)."""
    return _short[0]


def read_message(topic: bytes, header, descriptor_frame) -> list:
    """The frames ``[topic, header, *array views]`` of a shared-memory message, for the decoder.

    Maps the descriptor's segment (once per process), takes this subscriber's shared lock and checks the
    generation. The array views share one base array; when the last of them is garbage, the lock is let go.

    Raises
    ------
    StaleSegmentError
        The segment was written again (or is being written) since the descriptor was sent.
    SharedMemoryError
        A malformed descriptor, or a segment that is gone (its publisher exited) or is not the one named.
    """
    descriptor = unpack_descriptor(descriptor_frame)
    try:
        mapping = _acquire(descriptor)
    except OSError as exc:  # a lock or a read of the segment's header failed: the message cannot be trusted
        raise SharedMemoryError(f"segment {descriptor.inode} of process {descriptor.pid}: {exc}") from None
    base = np.frombuffer(mapping.view, dtype=np.uint8)  # read-only (the map is PROT_READ)
    _hold_until_garbage(base, mapping)
    frames = [memoryview(topic), getattr(header, "buffer", header)]
    frames.extend(base[offset:offset + nbytes].data for offset, nbytes in descriptor.entries)
    return frames


#: The weak references that let go of a message's mapping when its arrays' base is garbage, by their id (a weak
#: reference to an unhashable array cannot be a set member); each takes itself out when it fires.
_holds: dict[int, weakref.ref] = {}


def _hold_until_garbage(base: np.ndarray, mapping: _Mapping) -> None:
    """:func:`_release` ``mapping`` once ``base`` is garbage (a weak reference's callback: lighter than a
    ``weakref.finalize`` a message; at interpreter exit the kernel drops the process's locks anyway)."""
    def let_go(ref, mapping=mapping):
        _holds.pop(id(ref), None)
        _release(mapping)

    ref = weakref.ref(base, let_go)
    _holds[id(ref)] = ref


def _acquire(descriptor: Descriptor) -> _Mapping:
    now = time.monotonic()
    key = (descriptor.pid, descriptor.fd, descriptor.inode, descriptor.token)
    with _lock:
        if now >= _next_sweep[0]:
            _sweep_locked(now)
        mapping = _mappings.get(key)
        if mapping is None:
            mapping = _mappings[key] = _open(descriptor)
            used, allowed = descriptor_room(FD_GIVE_UP_SHARE)
            _short[0] = used > allowed
        if mapping.holders == 0:
            try:
                fcntl.flock(mapping.fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
            except BlockingIOError:
                raise StaleSegmentError(f"segment {descriptor.inode} of process {descriptor.pid} is being written "
                                        f"again (generation {descriptor.generation} recycled)") from None
            generation = _COUNTER.unpack_from(mapping.view, GENERATION_OFFSET)[0]
            if generation != descriptor.generation:
                fcntl.flock(mapping.fd, fcntl.LOCK_UN)
                raise StaleSegmentError(f"segment {descriptor.inode} of process {descriptor.pid} holds generation "
                                        f"{generation}, the descriptor generation {descriptor.generation}: recycled "
                                        "before this subscriber picked it up")
            mapping.generation = generation
        elif mapping.generation != descriptor.generation:  # held here: the publisher cannot have written it since
            raise StaleSegmentError(f"segment {descriptor.inode} of process {descriptor.pid}: descriptor generation "
                                    f"{descriptor.generation}, held generation {mapping.generation}")
        _count_pickup(mapping.fd)
        mapping.holders += 1
        mapping.last_used = now
    return mapping


def _count_pickup(fd: int, offset: int = PICKUPS_OFFSET) -> None:
    """Add one to the segment's pickup counter, or the let-go counter at ``RELEASES_OFFSET`` (a read-modify-write
    under a POSIX lock of those 8 bytes)."""
    fcntl.lockf(fd, fcntl.LOCK_EX, _COUNTER.size, offset)
    try:
        count = _COUNTER.unpack(os.pread(fd, _COUNTER.size, offset))[0]
        os.pwrite(fd, _COUNTER.pack(count + 1), offset)
    finally:
        fcntl.lockf(fd, fcntl.LOCK_UN, _COUNTER.size, offset)


def _release(mapping: _Mapping) -> None:
    with _lock:
        try:  # counted while this process still holds its lock: the publisher cannot be rewriting the header
            _count_pickup(mapping.fd, RELEASES_OFFSET)
        except (OSError, ValueError):
            pass  # a hint only: the publisher asks the lock after the lease
        mapping.holders -= 1
        mapping.last_used = time.monotonic()
        if mapping.holders == 0:
            try:
                fcntl.flock(mapping.fd, fcntl.LOCK_UN)
            except (OSError, ValueError):
                pass  # closed by a sweep already (cannot happen while held; kept safe)


#: Why a segment cannot be opened, by ``errno``: what the subscriber's log says beside the system's message.
_OPEN_HINTS = {
    errno.ENOENT: "its publisher exited or closed it",
    errno.EACCES: "the publisher's process is not dumpable, or a security module forbids /proc/<pid>/fd",
    errno.EPERM: "the publisher's process is not dumpable, or a security module forbids /proc/<pid>/fd",
    errno.EMFILE: "this process is at its file-descriptor limit, ulimit -n",
    errno.ENFILE: "the system is at its file limit",
}


def _open(descriptor: Descriptor) -> _Mapping:
    """Open and map the descriptor's segment; at the descriptor limit (``EMFILE``), once more after unmapping every
    segment no message here holds (kept only to be reused: each costs two descriptors, its own and the duplicate
    ``mmap`` keeps)."""
    path = f"/proc/{descriptor.pid}/fd/{descriptor.fd}"
    try:
        try:
            return _open_once(descriptor, path)
        except OSError as exc:
            if exc.errno != errno.EMFILE or not _close_unheld():
                raise
        return _open_once(descriptor, path)
    except OSError as exc:
        hint = _OPEN_HINTS.get(exc.errno or 0, "")
        raise SharedMemoryError(f"cannot open segment {path}: {exc.strerror}" + (f" ({hint})" if hint else "")) \
            from None


def _open_once(descriptor: Descriptor, path: str) -> _Mapping:
    # a forged descriptor may name any file of this user's processes: open regular files only (a device or a
    # terminal may act on open), without blocking (a FIFO) and never as the controlling terminal
    if not stat.S_ISREG(os.stat(path).st_mode):
        raise SharedMemoryError(f"{path} is not the segment the descriptor names (not a regular file)")
    fd = os.open(path, os.O_RDWR | os.O_NONBLOCK | os.O_NOCTTY | os.O_CLOEXEC)
    try:
        info = os.fstat(fd)
        if (not stat.S_ISREG(info.st_mode) or info.st_ino != descriptor.inode or info.st_uid != os.getuid()
                or info.st_size != descriptor.size):
            raise SharedMemoryError(f"{path} is not the segment the descriptor names (inode {info.st_ino}, "
                                    f"{info.st_size} bytes; expected inode {descriptor.inode}, {descriptor.size})")
        if _seals(fd) & SEALS != SEALS:  # a file that may shrink under the mapping
            raise SharedMemoryError(f"{path} is not the segment the descriptor names (not sealed against resizing)")
        view = mmap.mmap(fd, descriptor.size, prot=mmap.PROT_READ)
        magic, token = _HEADER.unpack_from(view)[:2]
        if magic != SEGMENT_MAGIC or token != descriptor.token:
            view.close()
            raise SharedMemoryError(f"{path} is not the segment the descriptor names (magic or token differ)")
    except BaseException:
        os.close(fd)
        raise
    return _Mapping(fd, view, descriptor.size, descriptor.pid)


def _seals(fd: int) -> int:
    """The file's seals; 0 for a file that cannot have any (not a memfd or tmpfs file)."""
    try:
        return fcntl.fcntl(fd, fcntl.F_GET_SEALS)
    except OSError:
        return 0


def _close_unheld() -> int:
    """Unmap every segment no message of this process holds (holding ``_lock``); how many were closed."""
    closed = 0
    for key, mapping in list(_mappings.items()):
        if not mapping.holders and mapping.close():
            del _mappings[key]
            closed += 1
    return closed


def _sweep_locked(now: float) -> None:
    """Unmap the segments no message here holds that were idle for a while or whose publisher is gone."""
    _next_sweep[0] = now + 1.0
    alive: dict[int, bool] = {}  # a publisher's process asked once a sweep (~60 us a question), not once a segment
    for key, mapping in list(_mappings.items()):
        if mapping.holders:
            continue
        if now - mapping.last_used < MAPPING_IDLE_S:
            pid = mapping.pid
            if pid not in alive:
                alive[pid] = process_alive(pid)
            if alive[pid]:
                continue
        if mapping.close():
            del _mappings[key]


def sweep_mappings() -> int:
    """Unmap the idle segments now (the graph runtime calls it once a second); the mappings left."""
    with _lock:
        _sweep_locked(time.monotonic())
        return len(_mappings)


def unmappable_subscribers(entries, topic: str, host: str, boot_id: str) -> list[str]:
    """The subscribers of ``topic`` in the graph's announcements ``entries`` (one a node) that cannot map segments of
    a process on ``host`` (``boot_id``): those of another host or kernel (or heard through a peer), and those that
    announce they take no shared memory (``DPTPU_SHM=off``, or given up); each as ``"NODE (pid P on HOST, why)"``."""
    named = []
    for entry in entries:
        subscriptions = [s for s in entry.get("subscriptions", ()) if s.get("topic") == topic]
        if not subscriptions:
            continue
        where = f"{entry.get('fqn', '?')} (pid {entry.get('pid', '?')} on {entry.get('host', '?')}"
        if entry.get("via") or entry.get("host") != host or entry.get("boot_id") != boot_id:
            named.append(where + ", another host)")
        elif any(s.get("shared_memory") is False for s in subscriptions):
            named.append(where + ", takes no shared memory)")
    return named


def mapped_segment_count() -> int:
    """Segments this process has mapped now (for tests and introspection)."""
    with _lock:
        return len(_mappings)
