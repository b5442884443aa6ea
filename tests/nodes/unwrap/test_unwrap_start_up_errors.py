"""A bad start-up value of the unwrap node names the parameter that holds it.

Before: ``-p model:=nosuch.onnx`` stopped the node with "invalid value False for parameter 'consensus': nosuch.onnx:
model file not found" (the three were checked together once the last, consensus, was declared).
"""
from __future__ import annotations

import pytest

from dptpu.nodes.harness import NodeHarness
from dptpu.nodes.unwrap import UnwrapNode


@pytest.mark.parametrize(("parameters", "message"), [
    ({"model": "nosuch.onnx"}, "invalid value 'nosuch.onnx' for parameter 'model': nosuch.onnx: model file not found"),
    ({"method": "bogus"}, "invalid value 'bogus' for parameter 'method': parameter method must be one of mf, mw, nt, "
                          "heterodyne; got 'bogus'"),
    ({"method": "heterodyne", "model": "shipped"}, "invalid value 'shipped' for parameter 'model': parameter model "
                                                   "refines a two-frequency method"),
])
def test_a_bad_start_up_value_names_its_parameter(parameters, message):
    with NodeHarness() as harness, pytest.raises(ValueError) as raised:
        harness.start(UnwrapNode, **parameters)
    assert str(raised.value).startswith(message), str(raised.value)


def test_the_good_start_up_values_still_load():
    with NodeHarness() as harness:
        node = harness.start(UnwrapNode, method="mw", model="none")
        assert (node.method, node.model_path, node.model) == ("mw", "none", None)
