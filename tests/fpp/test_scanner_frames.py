"""The scanner's TF frames: the projector's pose in the camera frame from the rig, the mount transform."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from dptpu.fpp.rig_model import DeviceModel, Rig
from dptpu.fpp.scanner_frames import IDENTITY_MOUNT, mount_pose, pose_to_xyz_quaternion, scanner_frames

K = np.array([[1000.0, 0, 320], [0, 1000.0, 240], [0, 0, 1]])


def _random_rig(rng, units):
    devices = [DeviceModel(K=K, dist=np.zeros(5), R=Rotation.random(random_state=rng).as_matrix(),
                           T=rng.uniform(-300, 300, 3), size=(640, 480)) for _ in range(2)]
    return Rig(camera=devices[0], projector=devices[1], units=units)


@pytest.mark.parametrize("seed", range(4))
def test_convention_projector_pose_maps_projector_coordinates_to_camera_coordinates(seed):
    rng = np.random.default_rng(seed)
    rig = _random_rig(rng, "mm")
    mount = mount_pose(IDENTITY_MOUNT, parent="tool0", child="scanner_optical_frame")
    _, projector = scanner_frames(rig, mount=mount, projector_frame="projector_optical_frame")
    assert (projector.parent, projector.child) == ("scanner_optical_frame", "projector_optical_frame")
    world_mm = rng.uniform(-500, 500, (10, 3))
    camera_m = (world_mm @ rig.camera.R.T + rig.camera.T) * 1e-3  # X_cam = R_c X_w + T_c, metres
    projector_m = (world_mm @ rig.projector.R.T + rig.projector.T) * 1e-3
    np.testing.assert_allclose(projector_m @ projector.R.T + projector.t, camera_m, atol=1e-12)
    q = projector.quaternion_xyzw()
    assert q[3] >= 0 and np.isclose(np.linalg.norm(q), 1.0)


def test_mount_transform_round_trips_and_refuses_a_non_unit_quaternion():
    rng = np.random.default_rng(7)
    R, t = Rotation.random(random_state=rng).as_matrix(), rng.uniform(-1, 1, 3)
    pose = mount_pose(pose_to_xyz_quaternion(R, t), parent="base_link", child="cam")
    np.testing.assert_allclose(pose.R, R, atol=1e-12)
    np.testing.assert_allclose(pose.t, t, atol=0)
    np.testing.assert_allclose(mount_pose(IDENTITY_MOUNT, parent="a", child="b").matrix(), np.eye(4))
    with pytest.raises(ValueError, match=r"quaternion \[qx, qy, qz, qw\] must have unit norm; got norm 2"):
        mount_pose([0, 0, 0, 0, 0, 0, 2], parent="a", child="b")
    with pytest.raises(ValueError, match=r"got norm 2 \(\[0\.0, 0\.0, 0\.0, 2\.0\]\)$"):  # plain numbers, no np.float64
        mount_pose([0, 0, 0, 0, 0, 0, 2], parent="a", child="b")
    with pytest.raises(ValueError, match=r"a mount transform is 7 finite numbers"):
        mount_pose([0, 0, 0, 1], parent="a", child="b")
