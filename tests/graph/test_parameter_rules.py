"""ParameterRules: settable parameters are checked (at start-up and at run time) and applied; read-only ones refused."""

from __future__ import annotations

import pytest

from dptpu.graph import InvalidParameterValueException, Node, Parameter
from dptpu.graph.parameter_rules import ParameterRules, at_least, frame_id, greater_than, one_of, within


class _Tuned(Node):
    def __init__(self, **options):
        super().__init__("tuned", **options)
        rules = ParameterRules(self)
        self.applied: list = []
        self.frame_id = rules.settable("frame_id", "scanner_optical_frame", check=frame_id)
        self.gain = rules.settable("gain", 0.5, check=within(0.0, 1.0), apply=self.applied.append)
        self.rig = rules.read_only("rig", "nominal", description="restart to change")


def test_settable_parameter_is_applied_and_a_bad_value_refused_with_its_reason(context):
    node = _Tuned(context=context)
    assert node.set_parameters([Parameter("frame_id", value="tool0")])[0].successful
    assert node.frame_id == "tool0"
    refused = node.set_parameters([Parameter("gain", value=1.5)])[0]
    assert (refused.successful, refused.reason) == (False, "gain must be within [0, 1]; got 1.5")
    assert node.get_parameter("gain").value == 0.5 and node.applied == []
    assert node.set_parameters([Parameter("gain", value=0.25)])[0].successful
    assert node.applied == [0.25]


def test_read_only_parameter_is_refused_and_keeps_its_start_up_value(context):
    node = _Tuned(context=context, parameter_overrides=[Parameter("rig", value="outside")])
    refused = node.set_parameters([Parameter("rig", value="other")])[0]
    assert (refused.successful, refused.reason) == (False, "Trying to set a read-only parameter: rig")
    assert node.rig == node.get_parameter("rig").value == "outside"
    assert node.describe_parameter("rig").read_only


def test_the_same_check_refuses_a_bad_start_up_value(context):
    with pytest.raises(InvalidParameterValueException, match=r"frame_id must not start with '/'"):
        _Tuned(context=context, parameter_overrides=[Parameter("frame_id", value="/tool0")])


@pytest.mark.parametrize(("check", "good", "bad", "reason"), [
    (within(0.0, 1.0), 1.0, -0.1, "must be within [0, 1]; got -0.1"),
    (at_least(0), 0, -1, "must be >= 0; got -1"),
    (greater_than(0.0), 1e-9, 0.0, "must be > 0; got 0.0"),
    (one_of(("mf", "nt")), "nt", "bogus", "must be one of mf, nt; got 'bogus'"),
    (frame_id, "base_link", "", "must not be empty (a TF frame id)"),
    (frame_id, "base_link", "tool 0", "must not contain spaces (a TF frame id); got 'tool 0'"),
])
def test_checks_accept_the_edge_and_refuse_beyond_it(check, good, bad, reason):
    assert check(good) is None
    assert check(bad) == reason
