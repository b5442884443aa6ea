"""The unwrap node's method, model and consensus at run time: checked together, the model loaded before it is used."""
from __future__ import annotations

import numpy as np
import pytest

from dptpu.graph import Parameter
from dptpu.messages import AbsolutePhase, PhaseMaps
from dptpu.nodes.harness import NodeHarness
from dptpu.nodes.unwrap import UnwrapNode


def test_method_model_and_consensus_are_checked_together_and_applied():
    from dptpu.models.inference import shipped_model_path

    if shipped_model_path() is None:
        pytest.skip("no shipped model in this build")
    with NodeHarness() as harness:
        node = harness.start(UnwrapNode, method="mf", model="none")
        alone = node.set_parameters([Parameter("consensus", value=True)])[0]
        assert not alone.successful and "consensus post-processes the network's fringe order" in alone.reason
        assert (node.consensus, node.model) == (False, None)
        # both at once: the consensus check sees the model being set with it
        assert node.set_parameters_atomically([Parameter("model", value="shipped"),
                                               Parameter("consensus", value=True)]).successful
        assert node.consensus and node.model is not None and node.model.serves("mf")
        refused = node.set_parameters([Parameter("method", value="heterodyne")])[0]
        assert not refused.successful and "refines a two-frequency method" in refused.reason
        assert node.method == "mf" and node.get_parameter("method").value == "mf"
        assert node.set_parameters([Parameter("method", value="nt")])[0].successful
        assert node.method == "nt" and node.model is not None


def test_a_method_that_cannot_unwrap_the_arriving_scans_is_refused_with_the_reason():
    """``param set /unwrap method mf`` on the MW 64/63 graph was accepted, then every scan FAILED ("mf needs a low
    frequency <= 1"); the projector's sequence is fixed while it runs, so the set is refused instead."""
    rng = np.random.default_rng(0)
    shape = (24, 32)
    with NodeHarness() as harness:
        node = harness.start(UnwrapNode, method="heterodyne", model="none")
        phase_pub = harness.publisher(PhaseMaps, "/scanner/phase")
        absolute = harness.collect(AbsolutePhase, "/scanner/absolute_phase")
        harness.connect()
        assert node.set_parameters([Parameter("method", value="mf")])[0].successful  # no scan seen yet: accepted
        assert node.set_parameters([Parameter("method", value="heterodyne")])[0].successful
        phase_pub.publish(PhaseMaps(sequence_id=1, frequencies=np.array([64.0, 63.0]),
                                    phases=rng.uniform(0, 2 * np.pi, (2, *shape)).astype(np.float32),
                                    modulation=np.full((2, *shape), 50.0, np.float32),
                                    valid=np.ones(shape, bool), fringe_axis="x", projector_width=912,
                                    projector_height=1140, steps=np.array([12, 12], np.uint32)))
        harness.wait(absolute, 1)
        refused = node.set_parameters([Parameter("method", value="mf")])[0]
        assert not refused.successful
        assert refused.reason.startswith("method mf cannot unwrap the scans arriving now: mf needs a low frequency "
                                         "<= 1")
        assert node.method == "heterodyne" and node.get_parameter("method").value == "heterodyne"
        assert node.set_parameters([Parameter("method", value="nt")])[0].successful  # 64, 63: NT serves them
