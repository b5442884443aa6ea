"""The cloud node's /tf_static: mount -> camera optical frame -> projector, latched, published again when set."""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from dptpu.fpp.calibration import save_rig
from dptpu.graph import Parameter
from dptpu.graph.qos import DurabilityPolicy, QoSProfile
from dptpu.messages import TFMessage
from dptpu.nodes.cloud import CloudNode
from dptpu.nodes.harness import NodeHarness
from tests.nodes.test_cloud_scene import plane_scene

LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)


def _pose(transform_stamped) -> tuple[np.ndarray, np.ndarray]:
    t, q = transform_stamped.transform.translation, transform_stamped.transform.rotation
    return Rotation.from_quat([q.x, q.y, q.z, q.w]).as_matrix(), np.array([t.x, t.y, t.z])


def test_tf_static_chains_mount_camera_and_projector_and_follows_param_set(tmp_path):
    rig = plane_scene().rig
    rig_path = save_rig(rig, tmp_path / "rig.yaml")
    mount = [0.01, -0.02, 0.15, *Rotation.from_euler("xyz", [10, -20, 90], degrees=True).as_quat()]
    with NodeHarness() as harness:
        node = harness.start(CloudNode, rig=str(rig_path), mount_frame="tool0", mount_transform=mount)
        tf = harness.collect(TFMessage, "/tf_static", LATCHED)  # joins late: the latched message still comes
        (first,) = harness.wait(tf, 1)
        mounted, projector = first.transforms
        assert (mounted.header.frame_id, mounted.child_frame_id) == ("tool0", "scanner_optical_frame")
        assert (projector.header.frame_id, projector.child_frame_id) == ("scanner_optical_frame",
                                                                         "projector_optical_frame")
        R, t = _pose(mounted)
        np.testing.assert_allclose(R, Rotation.from_quat(mount[3:]).as_matrix(), atol=1e-12)
        np.testing.assert_allclose(t, mount[:3])
        # the projector's optical centre, seen from the camera: -R_p^T T_p in world, into the camera frame
        R, t = _pose(projector)
        centre_cam_m = (rig.camera.R @ rig.projector.center + rig.camera.T) * rig.scale_to_m
        np.testing.assert_allclose(t, centre_cam_m, atol=1e-9)
        np.testing.assert_allclose(R, rig.camera.R @ rig.projector.R.T, atol=1e-9)

        refused = node.set_parameters([Parameter("mount_transform", value=[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 3.0])])[0]
        assert not refused.successful and "must have unit norm; got norm 3" in refused.reason
        assert node.set_parameters([Parameter("frame_id", value="camera_optical_frame")])[0].successful
        (_, second) = harness.wait(tf, 2)
        assert [(m.header.frame_id, m.child_frame_id) for m in second.transforms] == [
            ("tool0", "camera_optical_frame"), ("camera_optical_frame", "projector_optical_frame")]
