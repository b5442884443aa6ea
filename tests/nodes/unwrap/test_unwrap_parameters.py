"""The unwrap node's method, model and consensus at run time: checked together, the model loaded before it is used."""
from __future__ import annotations

import pytest

from dptpu.graph import Parameter
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
