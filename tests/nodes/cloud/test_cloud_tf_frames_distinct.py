"""The cloud node's three TF frames stay distinct: a ``param set`` (or a start-up value) that makes one equal to
another is refused, since /tf_static would then carry ``A -> A``, which tf2 refuses (TF_SELF_TRANSFORM).

Before: ``param set /cloud mount_frame scanner_optical_frame`` answered "Set parameter successful" and /tf_static
published ``scanner_optical_frame -> scanner_optical_frame``.
"""
from __future__ import annotations

import pytest

from dptpu.fpp.calibration import save_rig
from dptpu.graph import Parameter
from dptpu.graph.qos import DurabilityPolicy, QoSProfile
from dptpu.messages import TFMessage
from dptpu.nodes.cloud import CloudNode
from dptpu.nodes.harness import NodeHarness
from tests.nodes.test_cloud_scene import plane_scene

LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)


def test_a_frame_equal_to_another_is_refused_and_the_old_frames_stay(tmp_path):
    rig_path = save_rig(plane_scene().rig, tmp_path / "rig.yaml")
    with NodeHarness() as harness:
        node = harness.start(CloudNode, rig=str(rig_path), mount_frame="tool0")
        tf = harness.collect(TFMessage, "/tf_static", LATCHED)
        harness.wait(tf, 1)
        for name, value, other in [("mount_frame", "scanner_optical_frame", "frame_id"),
                                   ("frame_id", "tool0", "mount_frame"),
                                   ("projector_frame", "scanner_optical_frame", "frame_id"),
                                   ("frame_id", "projector_optical_frame", "projector_frame")]:
            (result,) = node.set_parameters([Parameter(name, value=value)])
            assert not result.successful
            assert result.reason == (f"{name} must differ from {other} (a TF frame cannot be its own parent or "
                                     f"child); got {value!r}")
        assert (node.frame_id, node.mount_frame, node.projector_frame) == (
            "scanner_optical_frame", "tool0", "projector_optical_frame")
        # a swap in one atomic set is fine: the check sees both new values
        assert node.set_parameters_atomically([Parameter("frame_id", value="tool0"),
                                               Parameter("mount_frame", value="scanner_optical_frame")]).successful
        swapped = [("scanner_optical_frame", "tool0"), ("tool0", "projector_optical_frame")]
        assert harness.spin_until(lambda: any(  # the latched first message may come twice (a late joiner's copy)
            [(m.header.frame_id, m.child_frame_id) for m in message.transforms] == swapped
            for message in list(tf.messages)), 30.0), [m.transforms for m in tf.messages]
        assert all((m.header.frame_id != m.child_frame_id) for message in tf.messages for m in message.transforms)


def test_equal_frames_at_start_up_stop_the_node(tmp_path):
    rig_path = save_rig(plane_scene().rig, tmp_path / "rig.yaml")
    with NodeHarness() as harness, pytest.raises(ValueError, match="projector_frame must differ from frame_id"):
        harness.start(CloudNode, rig=str(rig_path), projector_frame="scanner_optical_frame")
