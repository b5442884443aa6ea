"""The shared-memory path on a machine that limits it or is hostile to it: few file descriptors, a publisher that is
not dumpable, a subscriber at its descriptor limit, a forged descriptor naming a terminal, a process that truncates
a segment, a sandbox that hides the kernel's boot id.

The publisher is a real process (``tests/graph/nodes/shm_limited_publisher.py``) under a real ``setrlimit`` or
``prctl``; the subscriber is this process, which keeps every message it gets (a recorder, or a subscriber with a deep
queue: each kept message holds its segment).
"""

from __future__ import annotations

import gc
import os
import pty
import shlex
import shutil
import subprocess
import sys
import time

import numpy as np
import pytest

from dptpu.graph import Node, SingleThreadedExecutor, segment_pool, shared_memory
from dptpu.graph.segment_pool import SegmentPool
from dptpu.graph.shared_memory import (
    SharedMemoryConfig,
    SharedMemoryError,
    pack_descriptor,
    read_message,
    unpack_descriptor,
)
from dptpu.messages import Image
from dptpu.messages.std import Header

from .nodes.shm_limited_publisher import TOPIC, image_of
from .nodes.shm_peer import is_shared


def _keep_everything(context, count: int, publisher, timeout: float = 60.0) -> list:
    """Subscribe in this process, keep every message until ``count`` arrived; the kept messages."""
    kept: list = []
    node = Node("keeper", context=context)
    node.create_subscription(Image, TOPIC, kept.append, 100)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    publisher.wait_event("ready", timeout=30.0)
    deadline = time.monotonic() + timeout
    while len(kept) < count and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
    return kept


def _intact(kept: list) -> list[int]:
    """The indices of the kept messages, each checked bit for bit against the image the publisher made."""
    indices = []
    for msg in kept:
        index = int(msg.header.frame_id)
        assert np.array_equal(msg.to_array(), image_of(index)), index
        indices.append(index)
    return indices


def test_a_publisher_at_its_descriptor_limit_falls_back_to_zeromq_and_loses_nothing(context, spawn):
    # before: each kept message held a segment (two descriptors: the memfd and mmap's duplicate) until publish
    # raised EMFILE for every later message and the process could open no file (its announcements failed)
    nofile, count = 96, 60
    publisher = spawn("shm_limited_publisher", "--nofile", str(nofile), "--count", str(count), "--period", "0.005")
    kept = _keep_everything(context, count, publisher)
    report = publisher.wait_event("published", timeout=30.0)
    assert report["errors"] == []
    assert sorted(_intact(kept)) == list(range(count))  # every message, none lost, none changed
    assert 0 < report["shared"] < count and report["full"] == count - report["shared"]
    assert sum(is_shared(msg.data) for msg in kept) == report["shared"]
    # segments stop at FD_SHARE of the limit; ZeroMQ opens some more later (its connections): room is left
    assert report["most_fds"] < nofile * (1 + segment_pool.FD_SHARE) / 2
    assert publisher.wait_for_stderr("file descriptors open"), publisher.stderr
    assert "Too many open files" not in publisher.stderr
    assert publisher.stderr.count("shared memory of dptpu:limits:image") == 1  # one line, not one a message


def test_a_publisher_that_is_not_dumpable_sends_through_zeromq(context, spawn):
    # no other process of its user may open its /proc/<pid>/fd (root may): before, every subscriber of the same
    # (non-root) user lost its first SHM_GIVE_UP messages, then gave up shared memory for good
    count = 30
    publisher = spawn("shm_limited_publisher", "--undumpable", "--count", str(count), "--period", "0.005")
    kept = _keep_everything(context, count, publisher)
    report = publisher.wait_event("published", timeout=30.0)
    assert sorted(_intact(kept)) == list(range(count))
    assert report["shared"] == 0 and report["full"] == count and report["errors"] == []
    assert not any(is_shared(msg.data) for msg in kept)
    assert publisher.wait_for_stderr("is not dumpable"), publisher.stderr


_READER = """
import resource, sys
from dptpu.graph.shared_memory import read_message, SharedMemoryError
resource.setrlimit(resource.RLIMIT_NOFILE, (int(sys.argv[1]), resource.getrlimit(resource.RLIMIT_NOFILE)[1]))
read = failed = 0
for line in sys.stdin:
    try:
        views = read_message(b"/t", b"h", bytes.fromhex(line.strip()))
        read += 1
        del views  # let go: the mapping stays cached (idle), as a subscriber keeps it for the publisher's next write
    except SharedMemoryError as exc:
        failed += 1
        print("failed", exc, file=sys.stderr)
print(read, failed)
"""


def test_a_subscriber_at_its_descriptor_limit_unmaps_idle_segments_instead_of_losing_messages():
    # before: every new segment once the cached idle mappings had used the descriptors was refused (EMFILE), so
    # each message was lost until the mappings went idle for 5 s
    pool = SegmentPool(SharedMemoryConfig(lease_s=60.0, pool_bytes=64 << 20, key=b"k"), "dptpu:t")
    try:
        payload = [memoryview(np.arange(100_000, dtype=np.uint8))]
        descriptors = [pool.write(payload, readers=1).hex() for _ in range(40)]  # none picked up: 40 segments
        assert pool.segment_count == 40
        reader = subprocess.run([sys.executable, "-c", _READER, "48"], input="\n".join(descriptors),
                                capture_output=True, text=True, timeout=60)
        assert reader.stdout.split() == ["40", "0"], reader.stderr  # 2 descriptors a mapping: > 48 without it
    finally:
        pool.close()


def test_a_forged_descriptor_naming_a_terminal_is_refused_before_it_is_opened():
    # opening a terminal without O_NOCTTY can make it the controlling terminal of a process that has none; a
    # device may act on open: only regular files are opened at all
    master, terminal = pty.openpty()
    try:
        forged = pack_descriptor(os.getpid(), terminal, os.fstat(terminal).st_ino, bytes(16), 1, 4096, [(64, 8)])
        with pytest.raises(SharedMemoryError, match=r"is not the segment the descriptor names \(not a regular file"):
            read_message(b"/t", b"h", forged)
    finally:
        os.close(master)
        os.close(terminal)
        gc.collect()


_HOLDING_READER = """
import sys
import numpy as np
from dptpu.graph.shared_memory import read_message
views = read_message(b"/t", b"h", bytes.fromhex(sys.argv[1]))
print(int(np.frombuffer(views[2], np.uint8).sum()), flush=True)
sys.stdin.readline()
print(int(np.frombuffer(views[2], np.uint8).sum()), flush=True)
"""

_TRUNCATOR = """
import os, sys
fd = os.open(sys.argv[1], os.O_RDWR)
try:
    os.ftruncate(fd, 0)
except PermissionError:
    print("refused")
else:
    print("truncated")
"""


def test_no_process_can_shrink_a_segment_under_its_readers():
    # before: a process of the user that opened /proc/<pid>/fd/<n> and truncated the segment killed every reader
    # (and the publisher at its next write) with SIGBUS
    pool = SegmentPool(SharedMemoryConfig(lease_s=60.0, pool_bytes=64 << 20, key=b"k"), "dptpu:t")
    reader = None
    try:
        payload = np.arange(300_000, dtype=np.uint8)
        descriptor = pool.write([memoryview(payload)], readers=1)
        reader = subprocess.Popen([sys.executable, "-c", _HOLDING_READER, descriptor.hex()], stdin=subprocess.PIPE,
                                  stdout=subprocess.PIPE, text=True)
        expected = str(int(payload.sum()))
        assert reader.stdout.readline().strip() == expected
        path = f"/proc/{os.getpid()}/fd/{unpack_descriptor(descriptor).fd}"
        truncator = subprocess.run([sys.executable, "-c", _TRUNCATOR, path], capture_output=True, text=True,
                                   timeout=30)
        assert truncator.stdout.strip() == "refused", truncator.stderr
        reader.stdin.write("\n")
        reader.stdin.flush()
        assert reader.stdout.readline().strip() == expected
        assert reader.wait(timeout=30) == 0
        # and a subscriber maps no file that could shrink: a memfd like a segment but not sealed is refused
        unsealed = os.memfd_create("dptpu:unsealed", os.MFD_CLOEXEC)
        try:
            os.ftruncate(unsealed, 4096)
            os.pwrite(unsealed, shared_memory.SEGMENT_MAGIC + bytes(16), 0)
            forged = pack_descriptor(os.getpid(), unsealed, os.fstat(unsealed).st_ino, bytes(16), 0, 4096, [(64, 8)])
            with pytest.raises(SharedMemoryError, match=r"not sealed against resizing"):
                read_message(b"/t", b"h", forged)
        finally:
            os.close(unsealed)
    finally:
        if reader is not None and reader.poll() is None:
            reader.kill()
            reader.wait()
        pool.close()


@pytest.mark.skipif(os.geteuid() != 0 or shutil.which("unshare") is None,
                    reason="needs root and unshare to hide the boot id in a mount namespace")
def test_shared_memory_is_off_where_the_kernel_cannot_be_told_from_another_hosts():
    # before: without a boot id every host's processes in the first PID namespace (its inode is the same on all
    # Linux kernels) had one host key, so a peer on another host asked for, and got, descriptors it cannot map
    probe = ("from dptpu.graph.shared_memory import SharedMemoryConfig; "
             "print(SharedMemoryConfig.from_environment({}) is None)")
    hidden = subprocess.run(["unshare", "-m", "sh", "-c", "mount --bind /dev/null /proc/sys/kernel/random/boot_id "
                             f"&& exec {shlex.quote(sys.executable)} -c {shlex.quote(probe)}"],
                            capture_output=True, text=True, timeout=60)
    if hidden.returncode and "mount" in hidden.stderr:
        pytest.skip(f"no mount namespace here: {hidden.stderr.strip()}")
    assert hidden.stdout.strip() == "True", hidden.stderr
    seen = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=60)
    assert seen.stdout.strip() == "False", seen.stderr  # with the boot id: on


def test_a_subscriber_short_of_descriptors_takes_zeromq_before_it_loses_a_message(context, spawn):
    # before: a subscriber that held every message (a recorder behind its stream) mapped segments until the kernel
    # refused it a descriptor (EMFILE); it lost the next SHM_GIVE_UP messages, then gave up shared memory
    nofile, count = 96, 60
    subscriber = spawn("shm_limited_subscriber", "--nofile", str(nofile), "--count", str(count))
    subscriber.wait_event("ready", timeout=30.0)
    node = Node("limits_publisher", context=context)
    publisher = node.create_publisher(Image, TOPIC, 10)
    assert publisher.wait_for_subscriptions(1, timeout_sec=30.0)
    for index in range(count):
        publisher.publish(Image.from_array(image_of(index), "mono8", header=Header(frame_id=str(index))))
        time.sleep(0.005)
    done = subscriber.wait_event("done", timeout=60.0)
    assert done["received"] == list(range(count)) and done["lost_count"] == 0
    assert done["intact"] == count  # every held message still the publisher's, bit for bit
    assert 0 < done["shared"] < count == publisher.published_count
    assert publisher.shared_count == done["shared"]  # the rest went through ZeroMQ once it asked
    assert subscriber.wait_for_stderr("most of its file descriptors"), subscriber.stderr
    assert "Too many open files" not in subscriber.stderr


def test_a_loan_of_python_objects_is_refused_before_it_takes_a_segment(context):
    # before: the view of the segment as objects raised TypeError after the pool had lent the segment, which stayed
    # lent (exclusively locked) for good: each such call took a segment from the pool forever
    node = Node("object_loaner", context=context)
    publisher = node.create_publisher(Image, "/limits/objects", 10)
    for dtype in (object, [("x", "f4"), ("label", "O")]):
        with pytest.raises(ValueError, match="holds Python objects"):
            publisher.borrow_loaned_arrays([((300, 400), dtype)])
    assert publisher._pool.segment_count == 0
    (pixels,) = publisher.borrow_loaned_arrays([((300, 400), np.uint8)])  # plain data: a loan as always
    assert publisher._pool.segment_count == 1 and pixels.flags.c_contiguous
    publisher.return_loaned_arrays([pixels])
