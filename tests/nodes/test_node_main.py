"""What every node process sets up: freed memory kept, start-up objects frozen for the garbage collector."""
from __future__ import annotations

import gc

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
