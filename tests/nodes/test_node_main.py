"""What every node process sets up: freed memory kept, start-up objects frozen for the garbage collector; a quiet
stop on Ctrl-C while it still starts."""
from __future__ import annotations

import gc
import pkgutil
import subprocess
import sys

import pytest

import dptpu.nodes
from dptpu.cli.main import INTERRUPTED_EXIT_CODE
from dptpu.graph.node import Node
from dptpu.nodes import node_main
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
"""


@pytest.mark.parametrize("name", NODE_PACKAGES)
def test_ctrl_c_while_a_node_still_imports_ends_quietly(name):
    script = _INTERRUPT_WHILE_IMPORTING + f"runpy.run_module('dptpu.nodes.{name}', run_name='__main__', alter_sys=True)"
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60)
    assert (result.returncode, result.stderr) == (0, "")


def test_ctrl_c_after_the_node_is_built_but_before_it_spins_ends_quietly(monkeypatch, capsys):
    """A SIGINT during freeze_startup_objects' collection gave a traceback in a launch stopped 4 s after its start
    (the phase node); the node built is destroyed and the process exits 0. The interrupt is raised where the
    collection runs (a real SIGINT there is not deterministic)."""
    destroyed = []

    class Built(Node):
        def destroy_node(self):
            destroyed.append(self.get_name())
            return super().destroy_node()

    def interrupted() -> int:
        raise KeyboardInterrupt

    monkeypatch.setattr(node_main, "freeze_startup_objects", interrupted)
    assert run_node("phase", lambda: Built("phase"), ["phase"]) == 0
    assert destroyed == ["phase"] and capsys.readouterr().err == ""


def test_ctrl_c_while_the_dptpu_command_still_imports_ends_quietly():
    """``dptpu launch`` stopped within a second of its start printed the CLI's KeyboardInterrupt traceback."""
    script = _INTERRUPT_WHILE_IMPORTING + "from dptpu.cli.main import main\nsys.exit(main(['launch', 'sim_rig.yaml']))"
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60)
    assert (result.returncode, result.stderr) == (INTERRUPTED_EXIT_CODE, "")
