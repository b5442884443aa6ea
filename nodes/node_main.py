"""The ``main()`` every scanner node shares: init, build the node, spin until Ctrl-C or SIGTERM, clean up.

A node whose parameters are wrong cannot start: its constructor raises ``ValueError`` (or ``OSError`` for a
file it cannot open, ``ImportError`` for an optional part that is not installed) and the process prints one line
naming the node and the problem and exits with code 2, which ``dptpu launch`` reports; it never shows a traceback.

Two process-wide settings come with it:

- :func:`keep_freed_memory`: a scanner node allocates and frees megabyte arrays for every scan (frames, phase
  maps, clouds, ZeroMQ's receive buffers). glibc gives such blocks back to the kernel on ``free`` (``mmap``
  above 128 KiB, heap trimming), so the next scan page-faults the same amount again, in kernel time charged to
  every scan (docs/benchmarks.md, "Run 5", has the figures). The node keeps freed memory for reuse instead; its
  resident size stays at its peak (a few scans' worth). A node off the scan's hot path (the scan monitor) asks
  for :func:`return_freed_memory` instead (``run_node(..., keep_freed=False)``): in a heap that is never
  trimmed, the per-scan arrays it keeps for a while (clouds, phase maps, truths) wander over fresh pages of the
  free space, and its resident size crept up for thousands of scans (issue 19's soak).
- :func:`freeze_startup_objects`: once the node is built, the objects of its start-up (modules, the rig, tables,
  renders: tens of thousands) go to the garbage collector's permanent generation, so a full collection during
  the scans walks only what the scans made (otherwise it walks them all, a stall of that node in the scan it
  hits; docs/benchmarks.md, "Run 9"), and the youngest generation is collected every 5,000 allocations
  instead of 700.
- ``DPTPU_PROFILE_DIR``: when set, the node's main thread runs under :mod:`cProfile` and writes
  ``<dir>/<name>-<pid>.prof`` at exit (read it with ``python -m pstats``); how docs/benchmarks.md's per-node
  breakdown was taken. It counts the main thread's CPU time (``time.thread_time``: no waits, and no time lost
  to other processes on a busy machine), or the wall clock with ``DPTPU_PROFILE_CLOCK=wall``.
"""
from __future__ import annotations

import cProfile
import ctypes
import gc
import os
import sys
import time
from collections.abc import Callable
from typing import TypeVar

import dptpu.graph as rclpy
from dptpu.graph import ExternalShutdownException
from dptpu.graph.node import Node

__all__ = ["PROFILE_CLOCK_ENV", "PROFILE_ENV", "SETUP_ERRORS", "freeze_startup_objects", "keep_freed_memory",
           "return_freed_memory", "run_node", "spin_profiled"]

#: What a node's constructor raises for bad parameters, unreadable files or missing optional parts (exit code 2).
SETUP_ERRORS = (ValueError, OSError, ImportError)
#: Environment variable naming a folder for the nodes' cProfile output ("" or unset: no profiling).
PROFILE_ENV = "DPTPU_PROFILE_DIR"
#: ``wall``: the profile counts wall-clock time (waits included); default ``cpu``: the main thread's CPU time.
PROFILE_CLOCK_ENV = "DPTPU_PROFILE_CLOCK"

# glibc mallopt parameters (malloc.h) and the values set by keep_freed_memory.
_M_TRIM_THRESHOLD, _M_TOP_PAD, _M_MMAP_THRESHOLD = -1, -2, -3
_MMAP_THRESHOLD_BYTES = 32 * 1024 * 1024   # glibc's largest (HEAP_MAX_SIZE / 2 on 64-bit): a 640x480x24 stack is 7 MB
_TRIM_THRESHOLD_BYTES = 512 * 1024 * 1024  # free heap kept before trimming
_TOP_PAD_BYTES = 16 * 1024 * 1024          # heap grown in 16 MiB steps
_RETURNED_ABOVE_BYTES = 64 * 1024          # return_freed_memory: blocks from 64 KiB up mapped and unmapped alone


#: The class of node :func:`run_node` builds, so that its ``spin`` and ``on_exit`` may take that class.
NodeT = TypeVar("NodeT", bound=Node)


def keep_freed_memory() -> bool:
    """Make glibc's ``malloc`` keep freed blocks below 32 MiB for reuse instead of returning them to the kernel.

    Sets ``M_MMAP_THRESHOLD`` to 32 MiB, ``M_TRIM_THRESHOLD`` to 512 MiB and ``M_TOP_PAD`` to 16 MiB with
    ``mallopt`` (the same as the ``MALLOC_MMAP_THRESHOLD_``, ``MALLOC_TRIM_THRESHOLD_`` and ``MALLOC_TOP_PAD_``
    environment variables, which win when set). Per-scan arrays are then recycled from the heap without page
    faults. Not glibc (no ``mallopt``): nothing is changed.

    Returns
    -------
    bool
        True when the settings were applied.
    """
    if any(name in os.environ for name in ("MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_", "MALLOC_TOP_PAD_")):
        return False
    return _mallopt(((_M_MMAP_THRESHOLD, _MMAP_THRESHOLD_BYTES), (_M_TRIM_THRESHOLD, _TRIM_THRESHOLD_BYTES),
                     (_M_TOP_PAD, _TOP_PAD_BYTES)))


def return_freed_memory() -> bool:
    """Make glibc's ``malloc`` map a block of 64 KiB or more on its own and unmap it on ``free`` (unless a free
    chunk of the heap already holds it: glibc looks there first).

    Sets ``M_MMAP_THRESHOLD`` to 64 KiB, which also turns off glibc's moving threshold (it rises to the largest
    block freed, after which such blocks come from the heap again). Messages and arrays then never fragment the
    heap, and the resident size follows what the node holds; each large block costs its page faults again.
    ``MALLOC_MMAP_THRESHOLD_`` in the environment wins. Not glibc: nothing is changed.

    Returns
    -------
    bool
        True when the setting was applied.
    """
    if "MALLOC_MMAP_THRESHOLD_" in os.environ:
        return False
    return _mallopt(((_M_MMAP_THRESHOLD, _RETURNED_ABOVE_BYTES),))


def _mallopt(settings) -> bool:
    """glibc's ``mallopt(param, value)`` for each ``(param, value)``; True when every one was applied, False
    without glibc (nothing changed)."""
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    mallopt.restype = ctypes.c_int
    return all(mallopt(param, value) == 1 for param, value in settings)


#: Allocations (less deallocations) of container objects between two collections of the youngest generation.
_GC_YOUNG_THRESHOLD = 5000


def freeze_startup_objects() -> int:
    """Collect once, then move every object alive now to the collector's permanent generation (``gc.freeze``).

    A node builds everything it keeps for its lifetime at start-up; frozen, those objects are never walked again
    by a full collection, which otherwise stalls a node every few thousand messages (tens of thousands of
    start-up objects in the sim rig's nodes). The youngest generation is collected every :data:`_GC_YOUNG_THRESHOLD`
    allocations (Python's default: 700), the older ones as before.

    Returns
    -------
    int
        The number of objects frozen.
    """
    gc.collect()
    gc.freeze()
    _, older, oldest = gc.get_threshold()
    gc.set_threshold(_GC_YOUNG_THRESHOLD, older, oldest)
    return gc.get_freeze_count()


def spin_profiled(name: str, spin: Callable[[], None]) -> None:
    """Call ``spin()``; under cProfile when ``DPTPU_PROFILE_DIR`` is set (``<dir>/<name>-<pid>.prof`` at exit), timed
    by the main thread's CPU clock (``DPTPU_PROFILE_CLOCK=wall``: the wall clock)."""
    folder = os.environ.get(PROFILE_ENV, "")
    if not folder:
        spin()
        return
    # the main thread's CPU time (no waits, no time lost to other processes) unless DPTPU_PROFILE_CLOCK=wall
    clock = time.perf_counter if os.environ.get(PROFILE_CLOCK_ENV, "cpu") == "wall" else time.thread_time
    profiler = cProfile.Profile(clock)
    try:
        profiler.runcall(spin)
    finally:
        os.makedirs(folder, exist_ok=True)
        profiler.dump_stats(os.path.join(folder, f"{name}-{os.getpid()}.prof"))


def run_node(name: str, make_node: Callable[[], NodeT], argv=None, *, spin: Callable[[NodeT], None] | None = None,
             on_exit: Callable[[NodeT], None] | None = None, keep_freed: bool = True) -> int:
    """Run one node in this process until Ctrl-C, SIGTERM or shutdown; return the process exit code.

    Parameters
    ----------
    name : str
        The node's short name, for the error line (``cloud: error: ...``) and the profile's file name.
    make_node : callable
        Builds the node (its class); called after ``rclpy.init`` so it sees ``--ros-args``.
    argv : list of str, optional
        The command line (default ``sys.argv``), with ``--ros-args -p name:=value -r from:=to ...``.
    spin : callable, optional
        ``spin(node)`` runs the node (default ``rclpy.spin(node)``: until Ctrl-C, SIGTERM or shutdown).
    on_exit : callable, optional
        ``on_exit(node)`` runs after spinning, however it ended, before the node is destroyed.
    keep_freed : bool
        True (the pipeline's nodes): :func:`keep_freed_memory`; False (a node off the hot path that keeps
        messages for a while): :func:`return_freed_memory`.

    Returns
    -------
    int
        0 after a clean stop, 2 when the node could not start.
    """
    if keep_freed:
        keep_freed_memory()
    else:
        return_freed_memory()
    node = None
    try:
        rclpy.init(args=sys.argv if argv is None else argv)
        node = make_node()
        freeze_startup_objects()
    except SETUP_ERRORS as exc:
        print(f"{name}: error: {exc}", file=sys.stderr)
        rclpy.try_shutdown()
        return 2
    except KeyboardInterrupt:  # Ctrl-C (or the launcher stopping the graph) while the node was still starting
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
        return 0
    try:
        spin_profiled(name, lambda: (spin or rclpy.spin)(node))
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if on_exit is not None:
            on_exit(node)
        node.destroy_node()
        rclpy.try_shutdown()
    return 0
