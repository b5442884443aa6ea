"""The unwrap node writes its AbsolutePhase into a loaned shared-memory segment (issue 20): published without a
further copy, and bit for bit what it publishes through ZeroMQ alone (``DPTPU_SHM=off``)."""
from __future__ import annotations

import numpy as np
import pytest

from dptpu.messages import AbsolutePhase
from dptpu.nodes.harness import NodeHarness
from tests.graph.nodes.shm_peer import is_shared
from tests.nodes.test_cloud_scene import plane_scene
from tests.nodes.unwrap.test_unwrap_node import phase_maps, start


def _no_copy(*args, **kwargs):
    raise AssertionError("a loaned message was copied into a segment")


@pytest.mark.parametrize("method, frequencies", [("mf", (16.0, 1.0)), ("nt", (16.0, 15.0))])
def test_loaned_absolute_phase_equals_the_zeromq_one_bit_for_bit(monkeypatch, method, frequencies):
    scene = plane_scene()
    valid = np.ones(scene.lit.shape, bool)
    valid[40:60, 30:90] = False  # invalid pixels: NaN phase, order 0, reliability 0 in the message
    results = {}
    for shm in ("auto", "off"):
        monkeypatch.setenv("DPTPU_SHM", shm)
        with NodeHarness() as harness:
            node, source, absolute, _status = start(harness, method=method)
            if node.absolute_publisher._pool is not None:
                node.absolute_publisher._pool.write = _no_copy  # written once, in place
            for sequence_id in (1, 2):  # the second scan reuses the segment the first let go
                source.publish(phase_maps(scene, frequencies, sequence_id=sequence_id, valid=valid))
                harness.wait(absolute, sequence_id)
            msg = absolute.messages[-1]
            assert is_shared(msg.absolute_phase) == is_shared(msg.reliability) == (shm == "auto")
            assert node.absolute_publisher.shared_count == (2 if shm == "auto" else 0)
            results[shm] = [getattr(msg, name).copy() for name in AbsolutePhase.__annotations__
                            if isinstance(getattr(msg, name), np.ndarray) and getattr(msg, name).ndim == 2]
    assert len(results["auto"]) == 4
    for loaned, plain in zip(results["auto"], results["off"]):
        assert loaned.dtype == plain.dtype and np.array_equal(loaned, plain, equal_nan=loaned.dtype.kind == "f")
    absolute_phase, fringe_order, valid_out, reliability = results["auto"]
    assert not valid_out[40:60, 30:90].any() and valid_out.mean() > 0.9
    assert np.isnan(absolute_phase[~valid_out]).all() and (fringe_order[~valid_out] == 0).all()
    assert (reliability[~valid_out] == 0).all() and np.isfinite(absolute_phase[valid_out]).all()
