"""What every node process sets up: freed memory kept, start-up objects frozen for the garbage collector; a quiet
stop on Ctrl-C while it still starts."""
from __future__ import annotations

import gc
import pkgutil
import subprocess
import sys

import pytest

import dptpu.nodes
from dptpu.nodes.node_main import _GC_YOUNG_THRESHOLD, freeze_startup_objects, run_node


def test_freeze_startup_objects_moves_live_objects_out_of_full_collections():
    threshold = gc.get_threshold()
    kept = [[i] for i in range(1000)]  # objects a node builds at start and keeps (lists: tracked by the collector)
    try:
        frozen = freeze_startup_objects()
        assert frozen == gc.get_freeze_count() >= len(kept)
        assert gc.get_threshold() == (_GC_YOUNG_THRESHOLD, *threshold[1:])
        assert sum(1 for o in gc.get_objects() if o is kept[0]) == 0  # frozen: no generation (no collection) holds it
    finally:
        gc.unfreeze()
        gc.set_threshold(*threshold)
    assert any(o is kept[0] for o in gc.get_objects())


def test_ctrl_c_while_a_node_starts_ends_quietly(capsys):
    """The launcher stopping the graph while a node still starts (the sim loading its captures) gave a
    KeyboardInterrupt traceback; now the node exits 0 without one, as after Ctrl-C while spinning."""
    def starting():
        raise KeyboardInterrupt

    assert run_node("sim", starting, ["sim"]) == 0
    assert capsys.readouterr().err == ""

#: Every node package (each runs as ``python -m dptpu.nodes.NAME``).
NODE_PACKAGES = sorted(m.name for m in pkgutil.iter_modules(dptpu.nodes.__path__) if m.ispkg)

# A real SIGINT while the node's module imports numpy (deterministic: an import hook sends it), then what
# ``python -m dptpu.nodes.NAME`` does. Before: "Traceback ... KeyboardInterrupt" in the launch output.
_INTERRUPT_WHILE_IMPORTING = """
import os, runpy, signal, sys, time

class InterruptAtNumpy:
    def find_spec(self, name, path=None, target=None):
        if name == "numpy":
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(5.0)  # the KeyboardInterrupt is raised here, inside the import
        return None

sys.meta_path.insert(0, InterruptAtNumpy())
runpy.run_module(sys.argv_module, run_name="__main__", alter_sys=True)
"""


@pytest.mark.parametrize("name", NODE_PACKAGES)
def test_ctrl_c_while_a_node_still_imports_ends_quietly(name):
    script = _INTERRUPT_WHILE_IMPORTING.replace("sys.argv_module", repr(f"dptpu.nodes.{name}"))
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60)
    assert (result.returncode, result.stderr) == (0, "")
