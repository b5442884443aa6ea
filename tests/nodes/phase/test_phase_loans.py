"""The phase node computes its PhaseMaps and texture in loaned shared-memory segments (issue 20): published without
a copy, and bit for bit what it publishes through ZeroMQ alone (``DPTPU_SHM=off``)."""
from __future__ import annotations

import numpy as np
import pytest

from dptpu.messages import FringeFrame, Image, PhaseMaps
from dptpu.nodes.harness import NodeHarness, fringe_frames
from dptpu.nodes.phase import PhaseNode
from tests.graph.nodes.shm_peer import is_shared
from tests.nodes.test_cloud_scene import plane_scene

FREQUENCIES = (16.0, 1.0)


def _no_copy(*args, **kwargs):
    raise AssertionError("a loaned message was copied into a segment")


@pytest.mark.parametrize("steps", [12, 3])
def test_loaned_phase_maps_and_texture_equal_the_zeromq_ones_bit_for_bit(monkeypatch, steps):
    results = {}
    for shm in ("auto", "off"):
        monkeypatch.setenv("DPTPU_SHM", shm)
        scene = plane_scene()
        with NodeHarness() as harness:
            node = harness.start(PhaseNode, timeout_s=5.0)
            camera = harness.publisher(FringeFrame, "/camera/image_raw")
            phase = harness.collect(PhaseMaps, "/scanner/phase")
            texture = harness.collect(Image, "/scanner/texture")
            harness.connect()
            for publisher in (node.phase_publisher, node.texture_publisher):
                if publisher._pool is not None:
                    publisher._pool.write = _no_copy  # made in place: never copied into a segment
            for sequence_id in (1, 2):  # the second scan reuses what the first let go
                for frame in fringe_frames([scene.frames(f, steps=steps) for f in FREQUENCIES], FREQUENCIES,
                                           sequence_id=sequence_id):
                    camera.publish(frame)
                harness.wait(phase, sequence_id)
                harness.wait(texture, sequence_id)
            maps, image = phase.messages[-1], texture.messages[-1]
            assert is_shared(maps.phases) == is_shared(maps.valid) == is_shared(image.data) == (shm == "auto")
            assert node.phase_publisher.shared_count == (2 if shm == "auto" else 0)
            assert node.texture_publisher.shared_count == (2 if shm == "auto" else 0)
            results[shm] = (maps.phases.copy(), maps.modulation.copy(), maps.valid.copy(), image.to_array().copy())
    (phases, modulation, valid, texture), plain = results["auto"], results["off"]
    for loaned, other in ((phases, plain[0]), (valid, plain[2]), (texture, plain[3])):
        assert loaned.dtype == other.dtype and np.array_equal(loaned, other)
    # cv2.magnitude's SIMD and scalar paths round differently and split the row by its inputs' alignment (the
    # Eq. (2) sums' allocation, 4 or 8 bytes off): the same scan's modulation moves by one ulp between two scans
    # of one node, with or without loans; the loans add nothing to it
    np.testing.assert_array_max_ulp(modulation, plain[1], maxulp=1)
    assert valid.mean() > 0.9  # the plane's pixels are valid: the maps compared are real ones
