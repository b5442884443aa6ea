"""Camera-projector relative pose from every calibration view at once (stereo refinement).

A Bouguet toolbox calibration of a structured-light rig is two independent single-device calibrations: the
camera's and the projector's (an inverse camera), each with its own estimate of every board pose. Taking the
rig's world frame from one view (``Rc_1``, ``Tc_1`` of both files) makes the camera-projector pose the
difference of two independent single-view estimates, and each carries that view's error. This module keeps
both devices' intrinsics and distortion fixed and estimates the one relative pose that explains all views of
both devices together, by least squares on the reprojection errors:

    min over (R_rel, T_rel, {R_k, T_k})  sum_k  |x_cam,k - pi_cam(R_k X_k + T_k)|^2
                                              + |x_prj,k - pi_prj(R_rel (R_k X_k + T_k) + T_rel)|^2

with ``pi`` the device projection including distortion and skew (:mod:`dptpu.fpp.distortion`). This is what
OpenCV's ``stereoCalibrate`` does with ``CALIB_FIX_INTRINSIC``, written here with the skew the toolbox keeps.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from .distortion import distort, normalized_to_pixels
from .rig_model import DeviceModel


@dataclass(frozen=True)
class CalibrationViews:
    """Corner observations of a calibration: per view the board points and their images in both devices.

    object_points[k] : (M_k, 3) board coordinates; camera_points[k], projector_points[k] : (M_k, 2) pixels.
    """

    object_points: list
    camera_points: list
    projector_points: list

    def __post_init__(self):
        counts = {len(self.object_points), len(self.camera_points), len(self.projector_points)}
        if len(counts) != 1 or not self.object_points:
            raise ValueError("calibration views need the same number (> 0) of object, camera and projector "
                             f"point sets; got {len(self.object_points)}, {len(self.camera_points)}, "
                             f"{len(self.projector_points)}")
        for k, (obj, cam, prj) in enumerate(zip(self.object_points, self.camera_points, self.projector_points)):
            if obj.shape[1:] != (3,) or cam.shape != (len(obj), 2) or prj.shape != (len(obj), 2):
                raise ValueError(f"view {k + 1}: object points must be (M, 3) and image points (M, 2); got "
                                 f"{obj.shape}, {cam.shape}, {prj.shape}")


@dataclass(frozen=True)
class RelativePose:
    """Projector pose in the camera frame, ``X_prj = R X_cam + T``, and the fit's reprojection RMS (pixels)."""

    R: np.ndarray
    T: np.ndarray
    rms_camera_px: float
    rms_projector_px: float


def project(device: DeviceModel, points_device: np.ndarray) -> np.ndarray:
    """Pixels (M, 2) of points (M, 3) given in the device frame (distortion and skew applied)."""
    xy = points_device[:, :2] / points_device[:, 2:3]
    return normalized_to_pixels(distort(xy, device.dist), device.K)


def refine_relative_pose(camera: DeviceModel, projector: DeviceModel, views: CalibrationViews, *,
                         initial_board_poses, initial_relative) -> RelativePose:
    """Least-squares relative pose over all views, intrinsics fixed (see the module docstring).

    Parameters
    ----------
    initial_board_poses : list of (R (3, 3), T (3,))
        Board-to-camera pose of each view (e.g. Bouguet's ``Rc_k``, ``Tc_k`` of the camera file).
    initial_relative : (R (3, 3), T (3,))
        Starting relative pose, e.g. from view 1 of both files.
    """
    n_views = len(views.object_points)
    if len(initial_board_poses) != n_views:
        raise ValueError(f"need one initial board pose per view ({n_views}); got {len(initial_board_poses)}")

    def pack(relative, boards):
        parts = [Rotation.from_matrix(relative[0]).as_rotvec(), np.ravel(relative[1])]
        for R, T in boards:
            parts += [Rotation.from_matrix(R).as_rotvec(), np.ravel(T)]
        return np.concatenate(parts)

    def unpack(params):
        poses = params.reshape(-1, 6)
        return [(Rotation.from_rotvec(p[:3]).as_matrix(), p[3:]) for p in poses]

    def reprojection_errors(params):
        """Camera and projector reprojection errors, each (sum M_k, 2) pixels."""
        relative, *boards = unpack(params)
        camera_errors, projector_errors = [], []
        for (R_k, T_k), obj, cam, prj in zip(boards, views.object_points, views.camera_points,
                                             views.projector_points):
            in_camera = obj @ R_k.T + T_k
            in_projector = in_camera @ relative[0].T + relative[1]
            camera_errors.append(project(camera, in_camera) - cam)
            projector_errors.append(project(projector, in_projector) - prj)
        return np.concatenate(camera_errors), np.concatenate(projector_errors)

    def residuals(params):
        camera_errors, projector_errors = reprojection_errors(params)
        return np.concatenate([camera_errors.ravel(), projector_errors.ravel()])

    result = least_squares(residuals, pack(initial_relative, initial_board_poses), method="lm", x_scale="jac")
    relative = unpack(result.x)[0]
    camera_errors, projector_errors = reprojection_errors(result.x)
    return RelativePose(R=relative[0], T=relative[1],
                        rms_camera_px=float(np.sqrt(np.mean(np.sum(camera_errors ** 2, axis=1)))),
                        rms_projector_px=float(np.sqrt(np.mean(np.sum(projector_errors ** 2, axis=1)))))
