"""The running phase and unwrap nodes judge the network's confidence as ``dptpu unwrap`` does on the same capture: the
two frequencies' agreement floored at what the frames' rounding explains (PhaseMaps.steps carries the step counts)."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from dptpu.fpp.capture import load_sequence_images, read_capture
from dptpu.fpp.reconstruct import unwrap_capture
from dptpu.messages import AbsolutePhase, FringeFrame, PhaseMaps
from dptpu.nodes.harness import NodeHarness, fringe_frames
from dptpu.nodes.phase import PhaseNode
from dptpu.nodes.unwrap import UnwrapNode
from dptpu.sim.image_formation import SequenceSpec
from dptpu.sim.outside_rigs import OUTSIDE_RIGS
from dptpu.sim.render import render_capture
from dptpu.sim.scenes.random_scene import random_scene

FREQUENCIES = (20.0, 19.0)  # MW


@pytest.fixture(scope="module")
def model():
    from dptpu.models.inference import FringeOrderModel, shipped_model_path

    path = shipped_model_path()
    if path is None:
        pytest.skip("no shipped model")
    return FringeOrderModel.load(path)


@pytest.fixture(scope="module")
def capture(tmp_path_factory):
    """A clean (noiseless, 8-bit) 12-step twin capture of objects before a plane on an outside rig: the scan's
    agreement residual is about the rounding's, so dim pixels fall below 5 robust sigma for rounding alone."""
    rig = OUTSIDE_RIGS[0].rig((128, 96))
    scene = random_scene(rig, 501, objects=(2, 4), background_probability=1.0)
    folder = render_capture(rig, scene, [SequenceSpec(frequency=f, steps=12) for f in FREQUENCIES],
                            tmp_path_factory.mktemp("clean") / "capture", seed=1)
    return read_capture(folder)


def test_the_nodes_confidence_is_the_clis_with_the_rounding_floor(capture, model):
    from dptpu.models.refine import refine_capture_result

    classical = unwrap_capture(capture, method="mw", high=FREQUENCIES[0], low=FREQUENCIES[1])
    cli = refine_capture_result(classical, model)  # what dptpu unwrap --model publishes
    unfloored = refine_capture_result(dataclasses.replace(classical, quantization_noise=()), model)
    with NodeHarness() as harness:
        harness.start(PhaseNode, timeout_s=5.0)
        harness.start(UnwrapNode, method="mw", model=str(model.path), consensus=True, min_confidence=0.0)
        camera = harness.publisher(FringeFrame, "/camera/image_raw")
        maps = harness.collect(PhaseMaps, "/scanner/phase")
        absolute = harness.collect(AbsolutePhase, "/scanner/absolute_phase")
        harness.connect()
        stacks = [load_sequence_images(capture, sequence) for sequence in capture.sequences]
        for frame in fringe_frames(stacks, FREQUENCIES, sequence_id=5):
            camera.publish(frame)
        (sent,) = harness.wait(maps, 1, timeout_s=60.0)
        (node,) = harness.wait(absolute, 1, timeout_s=60.0)
    assert sent.steps.tolist() == [12, 12]
    both = node.valid & cli.valid
    assert both.sum() > 0.9 * cli.valid.sum()
    floor_matters = both & (np.abs(cli.reliability - unfloored.reliability) > 0.05)
    assert floor_matters.sum() > 200  # measured: 694 of 10,786 pixels
    difference = np.abs(node.reliability - cli.reliability)[both]
    assert np.mean(difference < 0.01) > 0.99, np.percentile(difference, [50, 99, 100])
    assert np.mean(np.abs(node.reliability - cli.reliability)[floor_matters] < 0.01) > 0.98
