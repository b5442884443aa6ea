"""Hand-eye calibration: where the scanner sits on (or beside) a robot, from robot poses and board views.

Two setups, one equation. With ``A_i`` the robot's flange pose for view ``i`` and ``B_i`` the board's pose in the
camera optical frame (``solvePnP`` on the board corners, the camera's intrinsics from the rig):

- **eye-in-hand** (the scanner on the flange, the board fixed): ``A_i = base_T_flange_i``; the unknowns are the
  *mount* ``X = flange_T_camera`` and the board's place ``Y = base_T_board``;
- **eye-to-hand** (the scanner fixed, the board on the flange): ``A_i = flange_T_base_i`` (the inverse); the
  unknowns are the mount ``X = base_T_camera`` and ``Y = flange_T_board``;

and in both ``A_i X B_i = Y`` for every view. ``P_T_C`` is the pose of frame ``C`` in frame ``P``
(``X_P = R X_C + t``, tf2's convention; :mod:`dptpu.fpp.scanner_frames`), translations in metres.

1. Initial values: solvers of ``AX = XB`` on the relative motions (``(A_j^-1 A_i) X = X (B_j B_i^-1)``) and of
   ``AX = ZB`` (``A_i X = Y B_i^-1``), each ``Y`` the mean of ``A_i X B_i``; the one whose board corners reproject
   best is kept. OpenCV's (:func:`cv2.calibrateHandEye`: Tsai, Park, Horaud, Andreff, Daniilidis;
   :func:`cv2.calibrateRobotWorldHandEye`: Shah, Li) where the installed OpenCV has them (4.x; the 5.0 wheels
   lack their Python bindings), and always two closed forms of our own: Park and Martin's (rotation by the
   orthogonal Procrustes fit of the motions' rotation vectors, then translation by linear least squares) and a
   Kronecker-product one for ``AX = ZB`` (both rotations as the null vector of
   ``[I (x) R_Ai, -(R_Bi^-T (x) I)]``, then both translations by linear least squares), as Shah's.
2. Joint refinement (:func:`scipy.optimize.least_squares`): ``X`` and ``Y`` (12 parameters) minimizing the
   reprojection error of every detected board corner through ``B_i = X^-1 A_i^-1 Y`` and the camera's model
   (distortion included): the board poses are not fitted per view but follow from the robot's, so the fit uses
   the robot's accuracy, not that of each ``solvePnP``.

References: F. Park and B. Martin, "Robot sensor calibration: solving AX = XB on the Euclidean group", IEEE Trans.
Robotics and Automation 10(5), 1994; M. Shah, "Solving the robot-world/hand-eye calibration problem using the
Kronecker product", J. Mechanisms and Robotics 5(3), 2013; R. Tsai and R. Lenz, "A new technique for fully
autonomous and efficient 3D robotics hand/eye calibration", IEEE Trans. Robotics and Automation 5(3), 1989;
A. Li, L. Wang and D. Wu, "Simultaneous robot-world and hand-eye calibration using dual-quaternions and Kronecker
product", Int. J. Physical Sciences 5(10), 2010.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import cv2
import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from .rig_calibration import Board
from .rig_model import DeviceModel
from .stereo_calibration import project

__all__ = ["SETUPS", "HandEyeResult", "board_in_camera", "calibrate_hand_eye", "invert", "rigid"]

#: The two setups, as ``dptpu calibrate hand-eye --setup`` names them.
SETUPS = ("eye-in-hand", "eye-to-hand")
#: OpenCV's AX = XB solvers and AX = ZB solvers tried for the initial value.
_AX_XB = {"tsai": cv2.CALIB_HAND_EYE_TSAI, "park": cv2.CALIB_HAND_EYE_PARK, "horaud": cv2.CALIB_HAND_EYE_HORAUD,
          "andreff": cv2.CALIB_HAND_EYE_ANDREFF, "daniilidis": cv2.CALIB_HAND_EYE_DANIILIDIS}
_AX_ZB = {"shah": cv2.CALIB_ROBOT_WORLD_HAND_EYE_SHAH, "li": cv2.CALIB_ROBOT_WORLD_HAND_EYE_LI}
#: The fewest views: three robot poses give two relative motions with (in general) different rotation axes.
MIN_VIEWS = 3
#: Motions turning less than this (degrees) say nothing about the axes; the ratio of the second to the first
#: singular value of the remaining unit axes below ``_MIN_AXIS_SPREAD`` means one axis (about 3 degrees apart).
_MIN_MOTION_DEG = 1.0
_MIN_AXIS_SPREAD = 0.05


def rigid(R: np.ndarray, t: ArrayLike) -> np.ndarray:
    """The 4x4 matrix ``[[R, t], [0, 1]]``."""
    out = np.eye(4)
    out[:3, :3], out[:3, 3] = R, np.asarray(t, dtype=np.float64).reshape(3)
    return out


def invert(T: np.ndarray) -> np.ndarray:
    """The inverse of a rigid 4x4 transform (``[[R^T, -R^T t], [0, 1]]``)."""
    R, t = T[:3, :3], T[:3, 3]
    return rigid(R.T, -R.T @ t)


@dataclass(frozen=True)
class HandEyeResult:
    """A hand-eye calibration (see the module docstring for the frames).

    Attributes
    ----------
    setup : str
        ``eye-in-hand`` or ``eye-to-hand``.
    mount : ndarray (4, 4)
        ``X``: the camera optical frame's pose in the flange (eye-in-hand) or the robot base (eye-to-hand), metres.
    board : ndarray (4, 4)
        ``Y``: the board's pose in the robot base (eye-in-hand) or the flange (eye-to-hand), metres.
    rms_px : float
        Reprojection RMS of every board corner after the joint refinement, camera pixels.
    view_rms_px : ndarray (N,)
        The same per view.
    initial_method : str
        The OpenCV solver whose result started the refinement.
    initial_rms_px : dict
        Reprojection RMS of each solver's result (pixels), before refinement.
    """

    setup: str
    mount: np.ndarray
    board: np.ndarray
    rms_px: float
    view_rms_px: np.ndarray
    initial_method: str
    initial_rms_px: dict = field(default_factory=dict)


def board_in_camera(corners_px: np.ndarray, board: Board, camera: DeviceModel) -> np.ndarray:
    """The board's pose in the camera optical frame (``cam_T_board``, metres) from its corners (``solvePnP``).

    Parameters
    ----------
    corners_px : ndarray (cols*rows, 2)
        Detected corners (:func:`dptpu.fpp.rig_calibration.find_board_corners`), 0-based pixels.
    board : Board
    camera : DeviceModel
        Intrinsics and distortion (its ``R``, ``T`` are not used).
    """
    object_m = board.object_points() * 1e-3  # (M, 3) metres
    ok, rvec, tvec = cv2.solvePnP(object_m, np.asarray(corners_px, dtype=np.float64).reshape(-1, 1, 2), camera.K,
                                  camera.dist, flags=cv2.SOLVEPNP_ITERATIVE)
    if not ok:
        raise ValueError("solvePnP found no board pose for these corners")
    return rigid(Rotation.from_rotvec(rvec.ravel()).as_matrix(), tvec.ravel())


def calibrate_hand_eye(flange_poses: Sequence[np.ndarray], corners_px: Sequence[np.ndarray], board: Board,
                       camera: DeviceModel, *, setup: str) -> HandEyeResult:
    """The mount of the scanner from robot flange poses and the board corners seen at each (module docstring).

    Parameters
    ----------
    flange_poses : sequence of ndarray (4, 4)
        ``base_T_flange`` of each view, metres (what the robot controller reports for its tool flange).
    corners_px : sequence of ndarray (cols*rows, 2)
        The board's corners in the camera image of each view.
    board : Board
    camera : DeviceModel
        The scanner camera's intrinsics and distortion (from the rig file).
    setup : str
        ``eye-in-hand`` or ``eye-to-hand``.

    Returns
    -------
    HandEyeResult

    Raises
    ------
    ValueError
        For an unknown setup, fewer than 3 views, a pose that is not rigid, or corner arrays of the wrong shape.
    """
    if setup not in SETUPS:
        raise ValueError(f"setup must be one of {', '.join(SETUPS)}; got {setup!r}")
    if len(flange_poses) != len(corners_px):
        raise ValueError(f"one set of board corners per robot pose; got {len(flange_poses)} poses and "
                         f"{len(corners_px)} views")
    if len(flange_poses) < MIN_VIEWS:
        raise ValueError(f"hand-eye calibration needs at least {MIN_VIEWS} views (robot poses with different "
                         f"rotation axes); got {len(flange_poses)}")
    corners = [np.asarray(c, dtype=np.float64).reshape(-1, 2) for c in corners_px]
    for i, c in enumerate(corners):
        if c.shape != (board.count, 2):
            raise ValueError(f"view {i}: corners must have shape ({board.count}, 2) for a {board.cols}x{board.rows} "
                             f"board; got {c.shape}")
    flange = [_checked_rigid(np.asarray(T, dtype=np.float64), f"flange pose {i}") for i, T in enumerate(flange_poses)]
    A = flange if setup == "eye-in-hand" else [invert(T) for T in flange]  # (4, 4) each
    _check_rotation_axes(A)
    B = [board_in_camera(c, board, camera) for c in corners]  # cam_T_board, (4, 4) each
    object_m = board.object_points() * 1e-3

    def rms(X, Y) -> float:
        return _rms_px(_residuals(_params(X, Y), A, corners, object_m, camera))

    candidates = {name: _with_board(X, A, B) for name, X in _ax_xb_solutions(A, B).items()}
    candidates.update(_ax_zb_solutions(A, B))
    initial_rms = {name: rms(X, Y) for name, (X, Y) in candidates.items()}
    best = min(initial_rms, key=lambda name: initial_rms[name])
    X0, Y0 = candidates[best]
    fit = least_squares(_residuals, _params(X0, Y0), args=(A, corners, object_m, camera), method="lm",
                        x_scale="jac")
    X, Y = _transforms(fit.x)
    return HandEyeResult(setup=setup, mount=X, board=Y, rms_px=_rms_px(fit.fun),
                         view_rms_px=np.array([_rms_px(view) for view in fit.fun.reshape(len(A), -1)]),
                         initial_method=best, initial_rms_px=initial_rms)


# -- private -----------------------------------------------------------------------------------------------------

def _check_rotation_axes(A) -> None:
    """ValueError when the robot's motions between views turn about (nearly) one axis only: the mount's
    translation along it is then undetermined (Tsai and Lenz's condition)."""
    rotvecs = np.stack([Rotation.from_matrix((invert(A[j]) @ A[i])[:3, :3]).as_rotvec()
                        for i in range(len(A)) for j in range(i + 1, len(A))])  # (P, 3)
    angles = np.linalg.norm(rotvecs, axis=1)
    axes = rotvecs[angles > np.radians(_MIN_MOTION_DEG)] / angles[angles > np.radians(_MIN_MOTION_DEG), None]
    spread = np.linalg.svd(axes, compute_uv=False) if len(axes) >= 2 else np.zeros(2)
    if len(axes) < 2 or spread[1] / spread[0] < _MIN_AXIS_SPREAD:
        raise ValueError(f"the robot's rotations between the views turn about one axis only (or less than "
                         f"{_MIN_MOTION_DEG:g} deg): the mount is undetermined along it; tilt the flange about at "
                         "least two different axes (20-40 deg each way)")


def _rms_px(residuals: np.ndarray) -> float:
    """RMS distance of corners from their reprojections: ``sqrt(mean(dx^2 + dy^2))`` (OpenCV's reprojection RMS)."""
    return float(np.sqrt(2.0 * np.mean(np.square(residuals))))


def _checked_rigid(T: np.ndarray, what: str) -> np.ndarray:
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise ValueError(f"{what} must be a finite 4x4 matrix; got shape {T.shape}")
    R = T[:3, :3]
    if not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0 or \
            not np.allclose(T[3], [0, 0, 0, 1]):
        raise ValueError(f"{what} is not a rigid transform (rotation orthonormal with det +1, last row 0 0 0 1)")
    return T


def _ax_xb_solutions(A, B) -> dict[str, np.ndarray]:
    """``X`` by each AX = XB solver: Park and Martin's, and OpenCV's (``cv2.calibrateHandEye`` with gripper2base =
    A_i, target2cam = B_i) where this OpenCV has it."""
    out = {"park-martin": _park_martin(A, B)}
    if not hasattr(cv2, "calibrateHandEye"):
        return out
    R_a, t_a = [T[:3, :3] for T in A], [T[:3, 3] for T in A]
    R_b, t_b = [T[:3, :3] for T in B], [T[:3, 3] for T in B]
    for name, method in _AX_XB.items():
        try:
            R, t = cv2.calibrateHandEye(R_a, t_a, R_b, t_b, method=method)
        except cv2.error:  # a solver that fails on these motions (e.g. a degenerate rotation) is left out
            continue
        if R is not None and np.all(np.isfinite(R)) and np.all(np.isfinite(t)):
            out[name] = rigid(_orthonormal(R), t.ravel())
    return out


def _ax_zb_solutions(A, B) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """``(X, Y)`` by each AX = ZB solver: ``cv2.calibrateRobotWorldHandEye`` solves ``cTw = cTg gTb bTw`` with
    ``cTw = B_i``, ``gTb = A_i^-1``; then ``X = cTg^-1`` and ``Y = bTw = (wTb)^-1``."""
    out = {"kronecker": _kronecker(A, B)}
    if not hasattr(cv2, "calibrateRobotWorldHandEye"):
        return out
    inverse_a = [invert(T) for T in A]
    R_w2c, t_w2c = [T[:3, :3] for T in B], [T[:3, 3] for T in B]
    R_b2g, t_b2g = [T[:3, :3] for T in inverse_a], [T[:3, 3] for T in inverse_a]
    for name, method in _AX_ZB.items():
        try:
            R_wb, t_wb, R_cg, t_cg = cv2.calibrateRobotWorldHandEye(R_w2c, t_w2c, R_b2g, t_b2g, method=method)
        except cv2.error:  # as above
            continue
        values = (R_wb, t_wb, R_cg, t_cg)
        if all(v is not None and np.all(np.isfinite(v)) for v in values):
            X = invert(rigid(_orthonormal(R_cg), t_cg.ravel()))
            Y = invert(rigid(_orthonormal(R_wb), t_wb.ravel()))
            out[name] = (X, Y)
    return out


def _park_martin(A, B) -> np.ndarray:
    """``X`` of ``A_ij X = X B_ij`` over all pairs of views: ``A_ij = A_j^-1 A_i``, ``B_ij = B_j B_i^-1``.

    Rotation: ``log R_Aij = R_X log R_Bij`` for every pair, ``R_X`` by the orthogonal Procrustes fit (SVD of
    ``sum alpha beta^T``); translation: ``(R_Aij - I) t_X = R_X t_Bij - t_Aij`` stacked, least squares.
    """
    motions = [(invert(A[j]) @ A[i], B[j] @ invert(B[i])) for i in range(len(A)) for j in range(i + 1, len(A))]
    alpha = np.stack([Rotation.from_matrix(a[:3, :3]).as_rotvec() for a, _ in motions])  # (P, 3)
    beta = np.stack([Rotation.from_matrix(b[:3, :3]).as_rotvec() for _, b in motions])  # (P, 3)
    R = _orthonormal(alpha.T @ beta)  # argmin sum |alpha - R beta|^2
    lhs = np.concatenate([a[:3, :3] - np.eye(3) for a, _ in motions])  # (3P, 3)
    rhs = np.concatenate([R @ b[:3, 3] - a[:3, 3] for a, b in motions])  # (3P,)
    return rigid(R, np.linalg.lstsq(lhs, rhs, rcond=None)[0])


def _kronecker(A, B) -> tuple[np.ndarray, np.ndarray]:
    """``(X, Y)`` of ``A_i X = Y C_i`` (``C_i = B_i^-1``) by the Kronecker product.

    Rotation: ``(I (x) R_Ai) vec R_X - (R_Ci^T (x) I) vec R_Y = 0`` (column-major ``vec``) for every view; the
    right singular vector of the smallest singular value gives both up to scale, each then made the nearest
    rotation. Translation: ``R_Ai t_X - t_Y = R_Y t_Ci - t_Ai`` stacked, least squares.
    """
    C = [invert(Bi) for Bi in B]
    eye = np.eye(3)
    rows = np.concatenate([np.hstack([np.kron(eye, a[:3, :3]), -np.kron(c[:3, :3].T, eye)]) for a, c in zip(A, C)])
    v = np.linalg.svd(rows)[2][-1]  # (18,)
    vec_x, vec_y = v[:9].reshape(3, 3).T, v[9:].reshape(3, 3).T  # column-major vec back to matrices
    sign = np.sign(np.linalg.det(vec_x))  # the null vector's sign is arbitrary: det(R) = +1 decides
    R_x, R_y = _orthonormal(sign * vec_x), _orthonormal(sign * vec_y)
    lhs = np.concatenate([np.hstack([a[:3, :3], -eye]) for a in A])  # (3N, 6)
    rhs = np.concatenate([R_y @ c[:3, 3] - a[:3, 3] for a, c in zip(A, C)])  # (3N,)
    t = np.linalg.lstsq(lhs, rhs, rcond=None)[0]
    return rigid(R_x, t[:3]), rigid(R_y, t[3:])


def _with_board(X: np.ndarray, A, B) -> tuple[np.ndarray, np.ndarray]:
    """``(X, Y)`` with ``Y`` the mean of ``A_i X B_i`` (rotations by their chordal mean)."""
    Ys = [Ai @ X @ Bi for Ai, Bi in zip(A, B)]
    R = Rotation.from_matrix(np.stack([Y[:3, :3] for Y in Ys])).mean().as_matrix()
    return X, rigid(R, np.mean([Y[:3, 3] for Y in Ys], axis=0))


def _orthonormal(R: np.ndarray) -> np.ndarray:
    """The rotation nearest to ``R`` (a solver's output is orthonormal only to its arithmetic)."""
    U, _, Vt = np.linalg.svd(np.asarray(R, dtype=np.float64))
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))])
    return U @ D @ Vt


def _params(X: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """12 parameters: rotation vectors and translations of ``X`` and ``Y``."""
    return np.concatenate([Rotation.from_matrix(X[:3, :3]).as_rotvec(), X[:3, 3],
                           Rotation.from_matrix(Y[:3, :3]).as_rotvec(), Y[:3, 3]])


def _transforms(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return (rigid(Rotation.from_rotvec(p[0:3]).as_matrix(), p[3:6]),
            rigid(Rotation.from_rotvec(p[6:9]).as_matrix(), p[9:12]))


def _residuals(p: np.ndarray, A, corners, object_m: np.ndarray, camera: DeviceModel) -> np.ndarray:
    """Reprojection errors (pixels) of every corner of every view through ``B_i = X^-1 A_i^-1 Y``."""
    X, Y = _transforms(p)
    inverse_x = invert(X)
    out = []
    for Ai, detected in zip(A, corners):
        B = inverse_x @ invert(Ai) @ Y  # cam_T_board
        in_camera = object_m @ B[:3, :3].T + B[:3, 3]  # (M, 3) metres
        out.append((project(camera, in_camera) - detected).ravel())
    return np.concatenate(out)
