"""``return_freed_memory`` (the scan monitor's malloc setting, issue 19's soak): a large block is mapped on its own
every time, never recycled through the heap, and unmapped when freed.

Checked in a fresh interpreter per setting (``mallopt`` is process-wide), with glibc's own ``mallinfo2``: ``hblkhd``
is the bytes in mapped blocks, ``arena`` the heap's size.
"""
from __future__ import annotations

import ctypes
import json
import subprocess
import sys

import pytest

_PROBE = r"""
import ctypes, json, sys
from dptpu.nodes.node_main import keep_freed_memory, return_freed_memory

class MallInfo2(ctypes.Structure):
    _fields_ = [(name, ctypes.c_size_t) for name in ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks",
                                                      "fsmblks", "uordblks", "fordblks", "keepcost")]

libc = ctypes.CDLL(None)
libc.mallinfo2.restype = MallInfo2
libc.malloc.restype = ctypes.c_void_p
libc.malloc.argtypes = (ctypes.c_size_t,)
libc.free.argtypes = (ctypes.c_void_p,)
applied = {"keep": keep_freed_memory, "return": return_freed_memory, "default": lambda: None}[sys.argv[1]]()
mapped = []
before = libc.mallinfo2().hblkhd  # the interpreter's own mapped blocks
# sizes above any free chunk the imports leave in the heap (glibc serves a request from a free chunk that fits before
# it looks at the threshold: 300 KB blocks came from the heap in a fresh clone's interpreter)
for size in (3_000_000, 3_000_000, 1_500_000, 7_000_000):  # the second 3 MB block: after the first was freed
    block = libc.malloc(size)
    mapped.append(libc.mallinfo2().hblkhd - before >= size)
    libc.free(block)
print(json.dumps({"applied": applied, "mapped": mapped, "mapped_after_free": libc.mallinfo2().hblkhd - before}))
"""


def _probe(setting: str) -> dict:
    result = subprocess.run([sys.executable, "-c", _PROBE, setting], capture_output=True, text=True, timeout=60,
                            env={"PATH": "/usr/bin:/bin"})
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout)


@pytest.mark.skipif(not hasattr(ctypes.CDLL(None), "mallinfo2"), reason="glibc >= 2.33 (mallinfo2) only")
def test_large_blocks_are_mapped_each_time_and_returned_on_free():
    returned = _probe("return")
    assert returned["applied"] is True
    assert returned["mapped"] == [True, True, True, True]  # never from the heap, whatever was freed before
    default = _probe("default")
    assert default["mapped"][0] and not default["mapped"][1]  # glibc's moving threshold: the heap's from then on
    kept = _probe("keep")
    assert kept["applied"] is True and kept["mapped"] == [False, False, False, False]  # the pipeline's nodes: heap
    for probe in (returned, default, kept):
        assert probe["mapped_after_free"] == 0  # nothing stays mapped
