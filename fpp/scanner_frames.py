"""The scanner's coordinate frames for TF: mount -> camera optical frame -> projector frame.

A robot needs the pose of the scanner's data in its own frames. The scanner's frames form a chain:

- ``mount``: where the scanner is fixed (a robot's flange ``tool0`` for eye-in-hand, its ``base_link`` or a
  world frame for eye-to-hand); the pose of the camera optical frame in it is the *mount transform* (identity by
  default; ``dptpu calibrate hand-eye`` measures it, :mod:`dptpu.fpp.hand_eye`).
- the camera optical frame (x right, y down, z forward; the frame of the clouds and depth images);
- the projector frame (the projector as an inverse camera, same axes), from the rig's calibration.

Convention (tf2's): a :class:`FramePose` ``(parent, child, R, t)`` is the pose of ``child`` in ``parent``,
``X_parent = R X_child + t``, ``t`` in metres. The rig's extrinsics map the world into each device
(``X_dev = R_dev X_world + T_dev``), so the projector in the camera frame is
``R = R_c R_p^T``, ``t = (T_c - R_c R_p^T T_p) * scale_to_m``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from .rig_model import Rig

__all__ = ["FramePose", "IDENTITY_MOUNT", "mount_pose", "pose_to_xyz_quaternion", "projector_in_camera",
           "scanner_frames"]

#: ``[x, y, z, qx, qy, qz, qw]`` of the identity (metres; quaternion ``w`` last, as tf2's static publisher).
IDENTITY_MOUNT = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0)
#: How far from 1 a mount quaternion's norm may be (a rounded value written by hand or another tool).
_UNIT_TOLERANCE = 1e-3


@dataclass(frozen=True)
class FramePose:
    """The pose of frame ``child`` in frame ``parent``: ``X_parent = R X_child + t``.

    Attributes
    ----------
    parent, child : str
        Frame ids.
    R : ndarray (3, 3) float64
        Rotation, orthonormal with determinant +1.
    t : ndarray (3,) float64
        Translation, metres.
    """

    parent: str
    child: str
    R: np.ndarray
    t: np.ndarray

    def quaternion_xyzw(self) -> np.ndarray:
        """The rotation as a unit quaternion ``(x, y, z, w)`` with ``w >= 0``, (4,) float64."""
        q = Rotation.from_matrix(self.R).as_quat()  # (x, y, z, w), scipy's order
        return -q if q[3] < 0 else q

    def matrix(self) -> np.ndarray:
        """The homogeneous 4x4 matrix ``[[R, t], [0, 1]]``."""
        out = np.eye(4)
        out[:3, :3], out[:3, 3] = self.R, self.t
        return out


def mount_pose(values: Sequence[float], *, parent: str, child: str) -> FramePose:
    """The pose of ``child`` in ``parent`` from ``[x, y, z, qx, qy, qz, qw]`` (metres; quaternion ``w`` last).

    Raises
    ------
    ValueError
        When ``values`` is not 7 finite numbers or the quaternion is not of unit norm (within 1e-3; it is then
        normalized).
    """
    v = np.asarray(values, dtype=np.float64)
    if v.shape != (7,) or not np.all(np.isfinite(v)):
        raise ValueError(f"a mount transform is 7 finite numbers [x, y, z, qx, qy, qz, qw] (metres, quaternion w "
                         f"last); got {list(values)}")
    norm = float(np.linalg.norm(v[3:]))
    if abs(norm - 1.0) > _UNIT_TOLERANCE:
        raise ValueError(f"the mount transform's quaternion [qx, qy, qz, qw] must have unit norm; got norm {norm:.6g} "
                         f"({v[3:].tolist()})")
    return FramePose(parent, child, Rotation.from_quat(v[3:] / norm).as_matrix(), v[:3].copy())


def pose_to_xyz_quaternion(R: np.ndarray, t: np.ndarray) -> list[float]:
    """``[x, y, z, qx, qy, qz, qw]`` of a pose (the inverse of :func:`mount_pose`)."""
    q = FramePose("", "", np.asarray(R, dtype=np.float64), np.asarray(t, dtype=np.float64)).quaternion_xyzw()
    return [float(x) for x in (*np.asarray(t, dtype=np.float64).reshape(3), *q)]


def projector_in_camera(rig: Rig, *, camera_frame: str, projector_frame: str) -> FramePose:
    """The projector frame's pose in the camera optical frame, from the rig's extrinsics, in metres."""
    R_c, T_c = rig.camera.R, np.asarray(rig.camera.T, dtype=np.float64).reshape(3)
    R_p, T_p = rig.projector.R, np.asarray(rig.projector.T, dtype=np.float64).reshape(3)
    R = R_c @ R_p.T
    return FramePose(camera_frame, projector_frame, R, (T_c - R @ T_p) * rig.scale_to_m)


def scanner_frames(rig: Rig, *, mount: FramePose, projector_frame: str) -> list[FramePose]:
    """The scanner's static frames: ``mount`` (its parent -> the camera optical frame ``mount.child``), then the
    camera optical frame -> ``projector_frame``."""
    return [mount, projector_in_camera(rig, camera_frame=mount.child, projector_frame=projector_frame)]
