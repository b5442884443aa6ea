"""The sim node's raycast renders carry the rig's geometry-stage effects, as ``dptpu sim render`` does.

Found by the outside tester of issue 16 (16E): with ``pixel_footprint`` in the rig file, ``dptpu launch
launch/sim_rig.yaml source:=raycast rig:=...`` gave the same scans, point for point, as without it (the node traced
one ray per pixel and applied the pattern and camera stages only), so the main job never saw the mixed pixels at
depth edges that ``dptpu eval cloud`` and ``dptpu sim render --supersample`` render.
"""
from dataclasses import replace

import numpy as np
from scipy import ndimage

from dptpu.fpp.capture import load_sequence_images, read_capture
from dptpu.nodes.sim.source import raycast_scenes
from dptpu.sim.image_formation import SequenceSpec
from dptpu.sim.render import render_capture
from dptpu.sim.rig import nominal_rig
from dptpu.sim.scenes import load_scene

_FOOTPRINT = {"name": "pixel_footprint", "samples": 3, "blur_sigma_px": 0.5}
_NOISE = {"name": "sensor_noise", "read_noise_dn": 1.0, "gain_dn_per_electron": 0.0}


def test_node_frames_equal_the_twin_render_with_a_pixel_footprint(tmp_path):
    rig = replace(nominal_rig(camera_size=(64, 48)), effects=(_FOOTPRINT, _NOISE))
    node = raycast_scenes(rig, ["sphere"], [(16.0, 4)], seed=3)[0].frames[(16.0, 4)]  # (4, 48, 64)
    folder = render_capture(rig, load_scene("sphere", rig), [SequenceSpec(16.0, 4)], tmp_path / "cap", seed=3)
    capture = read_capture(folder)
    rendered = load_sequence_images(capture, capture.sequences[0])
    np.testing.assert_array_equal(node, rendered)

    # the footprint acts: a pixel beside the sphere whose centre ray misses it integrates some of its light
    # (measured: 68 of the 68 pixels of the ring, up to 35 DN); one ray per pixel leaves them black
    footprint = raycast_scenes(replace(rig, effects=(_FOOTPRINT,)), ["sphere"], [(16.0, 4)], seed=3)[0]
    centre_only = raycast_scenes(replace(rig, effects=()), ["sphere"], [(16.0, 4)], seed=3)[0]
    hit = np.isfinite(centre_only.depth_m)
    ring = ~hit & (ndimage.binary_dilation(hit, np.ones((3, 3), bool)))
    assert ring.sum() > 20
    assert centre_only.frames[(16.0, 4)][:, ring].max() == 0
    assert (footprint.frames[(16.0, 4)][:, ring].max(axis=0) > 0).mean() > 0.5
