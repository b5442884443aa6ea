"""Calibrating a camera-projector rig from checkerboard poses: the camera by Zhang, the projector as an inverse camera.

One calibration pose is a checkerboard seen by the camera while the projector casts phase-shifted fringes along
projector x (vertical stripes) and along projector y (horizontal stripes). Per pose:

1. the camera image of the board (the white reference, else the fringe average ``A`` of Eq. (2)) gives the inner
   corners, OpenCV ``findChessboardCorners`` + ``cornerSubPix``;
2. the absolute phase of both fringe directions (Eqs. (2)-(9)) gives every camera pixel its projector coordinate
   ``x_p = Phi_x W_p / (2 pi f_x)``, ``y_p = Phi_y H_p / (2 pi f_y)``; a local homography fitted to the pixels
   around each corner (weighted by the fringe modulation, the board being a plane) carries the corner to the
   projector: the projector "sees" the same corners (Zhang & Huang 2006, the projector as an inverse camera);
3. across poses, ``calibrateCamera`` (Zhang 2000) calibrates each device alone, then the relative pose of the
   projector is refined over every pose with both intrinsics fixed
   (:func:`dptpu.fpp.stereo_calibration.refine_relative_pose`, OpenCV's ``stereoCalibrate`` with
   ``CALIB_FIX_INTRINSIC``).

The rig that comes out has its world frame at the camera (camera ``R = I``, ``T = 0``); the projector's
``R``, ``T`` map camera coordinates to projector coordinates, in the board's unit (``square_mm``: mm).

On disk (docs/calibration.md) a calibration pose is a folder holding two ``dptpu-capture/1`` folders, ``x/``
(``fringe_axis: x``) and ``y/`` (``fringe_axis: y``), each with two or more phase sequences (an ``f <= 1``
sequence for multi-frequency unwrapping, otherwise a heterodyne set) and optionally ``references.white``.

References
----------
Z. Zhang, "A flexible new technique for camera calibration", IEEE TPAMI 22(11), 2000.
S. Zhang, P. S. Huang, "Novel method for structured light system calibration", Opt. Eng. 45(8), 2006.
DP-TPU paper, "Digital twin" section and Table 1 (``shared/seed/dp-tpu-paper.md``).
"""
from __future__ import annotations

import re
import sys
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from tqdm import tqdm

from .calibration import DeviceModel, Rig
from .capture import Capture, load_reference, load_sequence_images, read_capture
from .reconstruct import CaptureResult, unwrap_capture
from .stereo_calibration import CalibrationViews, RelativePose, refine_relative_pose

__all__ = [
    "Board",
    "parse_board",
    "find_board_corners",
    "projector_points_at",
    "DeviceCalibration",
    "RigCalibration",
    "PoseObservation",
    "calibrate_device",
    "calibrate_rig",
    "observe_pose",
    "find_pose_folders",
    "calibrate_from_folders",
]

_AXES = ("x", "y")
# A corner's projector coordinate needs at least this share of its window's pixels to be usable.
_MIN_WINDOW_FILL = 0.3
#: Pixels whose weight (modulation) is below this fraction of the largest in their window are left out of the
#: local homography of :func:`projector_points_at`.
MIN_RELATIVE_WEIGHT = 0.3


# --------------------------------------------------------------------------------------------------
# The board
# --------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Board:
    """A checkerboard: ``cols`` x ``rows`` inner corners, squares of ``square_mm``.

    Convention: board point ``(i, j)`` (column ``i``, row ``j``) lies at ``(i*square_mm, j*square_mm, 0)`` in the
    board frame; points are listed row by row, as ``findChessboardCorners`` returns them.
    """

    cols: int
    rows: int
    square_mm: float

    def __post_init__(self):
        if int(self.cols) < 3 or int(self.rows) < 3:
            raise ValueError(f"a board needs at least 3x3 inner corners; got {self.cols}x{self.rows}")
        if not (np.isfinite(self.square_mm) and self.square_mm > 0):
            raise ValueError(f"board square size must be > 0 mm; got {self.square_mm}")
        object.__setattr__(self, "cols", int(self.cols))
        object.__setattr__(self, "rows", int(self.rows))
        object.__setattr__(self, "square_mm", float(self.square_mm))

    @property
    def count(self) -> int:
        """Number of inner corners, ``cols * rows``."""
        return self.cols * self.rows

    def object_points(self) -> np.ndarray:
        """Board-frame corners (cols*rows, 3) float64, mm, row by row."""
        j, i = np.mgrid[0:self.rows, 0:self.cols]
        return np.stack([i.ravel(), j.ravel(), np.zeros(self.count)], axis=1) * self.square_mm


def parse_board(text: str) -> Board:
    """``"COLSxROWS:SQUARE_MM"`` (inner corners, square edge in mm), e.g. ``"9x6:15"``, as a :class:`Board`."""
    match = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*:\s*([0-9.eE+-]+)\s*", str(text))
    if not match:
        raise ValueError(f"--board must be COLSxROWS:SQUARE_MM (inner corners, square edge in mm), e.g. 9x6:15; "
                         f"got {text!r}")
    try:
        square = float(match.group(3))
    except ValueError:
        raise ValueError(f"--board square size must be a number of mm; got {match.group(3)!r}") from None
    return Board(int(match.group(1)), int(match.group(2)), square)


def find_board_corners(image: np.ndarray, board: Board, *, where: str = "image") -> np.ndarray:
    """Inner corners of ``board`` in a camera image, sub-pixel (Zhang's first step).

    Parameters
    ----------
    image : ndarray (H, W)
        Mono image, any real dtype (scaled to 8 bits for the detector; sub-pixel refinement on float).
    board : Board
    where : str
        Names the image in the error message (e.g. the pose folder).

    Returns
    -------
    ndarray (cols*rows, 2) float64
        Corner pixels, 0-based (centre of the top-left pixel = (0, 0)), in ``findChessboardCorners``' order.

    Raises
    ------
    ValueError
        The image is not 2-D, or the board is not found ("no 9x6 checkerboard corners found in ...").
    """
    image = np.asarray(image)
    if image.ndim != 2:
        raise ValueError(f"{where}: the board image must have shape (H, W); got {image.shape}")
    values = image.astype(np.float64)
    low, high = np.percentile(values, [0.5, 99.5])
    scaled = np.clip((values - low) * (255.0 / max(high - low, 1e-9)), 0, 255).astype(np.uint8)
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
    found, corners = cv2.findChessboardCorners(scaled, (board.cols, board.rows), flags=flags)
    if not found or corners is None or len(corners) != board.count:
        raise ValueError(f"{where}: no {board.cols}x{board.rows} checkerboard corners found "
                         f"(check --board: inner corners, not squares; and that the whole board is in view)")
    spacing = np.median(np.linalg.norm(np.diff(corners.reshape(board.rows, board.cols, 2), axis=1), axis=-1))
    half = int(np.clip(spacing / 4.0, 2, 11))
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 100, 1e-4)
    refined = cv2.cornerSubPix(scaled.astype(np.float32), corners.astype(np.float32), (half, half), (-1, -1),
                               criteria)
    return refined.reshape(-1, 2).astype(np.float64)


# --------------------------------------------------------------------------------------------------
# Corners in the projector: local homographies on the phase maps
# --------------------------------------------------------------------------------------------------

def projector_points_at(points_px: np.ndarray, projector_xy: np.ndarray, weights: np.ndarray, *,
                        window_px: int = 6) -> tuple[np.ndarray, np.ndarray]:
    """Projector coordinates of sub-pixel camera points, by a local homography fitted to the phase maps.

    Parameters
    ----------
    points_px : ndarray (M, 2)
        Camera pixels (u, v), 0-based, e.g. board corners.
    projector_xy : ndarray (H, W, 2)
        Projector coordinate (x_p, y_p) of every camera pixel, projector pixels (from the absolute phase of a
        vertical and a horizontal fringe sequence); any value where ``weights`` is 0.
    weights : ndarray (H, W)
        Quality of each pixel, >= 0 (0 = invalid), inversely proportional to its phase noise: the fringe
        modulation ``B`` (the phase noise is ``sqrt(2/N) sigma / B``, Eq. (2)).
    window_px : int
        Half-size of the square window of camera pixels around each point.

    Returns
    -------
    projector_points : ndarray (M, 2) float64
        (x_p, y_p) at each point; NaN where ``ok`` is False.
    ok : ndarray (M,) bool
        False where fewer than 30 % of the window's pixels are usable.

    Notes
    -----
    A plane maps to both image planes by homographies, so camera -> projector is a homography ``H`` on a
    flat board (lens distortion is negligible inside a window). Per point: pixels whose weight is below
    :data:`MIN_RELATIVE_WEIGHT` of the window's largest are left out (a board's dark squares: their phase is
    noisy and their fringe orders often wrong); weighted DLT (weights squared: inverse phase variance) on
    centred, scaled coordinates (batched SVD); one refit without pixels whose residual exceeds
    ``max(0.5, 4 * median)`` projector pixels (a wrong fringe order, a specular glint); ``H`` evaluated at the
    point.
    """
    points = np.asarray(points_px, dtype=np.float64)
    xy = np.asarray(projector_xy, dtype=np.float64)
    weights = np.asarray(weights, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 2:
        raise ValueError(f"points_px must have shape (M, 2); got {points.shape}")
    if xy.ndim != 3 or xy.shape[2] != 2:
        raise ValueError(f"projector_xy must have shape (H, W, 2); got {xy.shape}")
    if weights.shape != xy.shape[:2]:
        raise ValueError(f"weights must have shape (H, W) = {xy.shape[:2]} like projector_xy; got {weights.shape}")
    height, width = weights.shape
    offsets = np.arange(-window_px, window_px + 1)
    dv, du = (a.ravel() for a in np.meshgrid(offsets, offsets, indexing="ij"))  # (P,)
    centre = np.rint(points).astype(np.int64)  # (M, 2)
    u = centre[:, :1] + du[None]  # (M, P)
    v = centre[:, 1:] + dv[None]
    inside = (u >= 0) & (u < width) & (v >= 0) & (v < height)
    uc, vc = np.clip(u, 0, width - 1), np.clip(v, 0, height - 1)
    w = np.where(inside, weights[vc, uc], 0.0)  # (M, P)
    target = xy[vc, uc]  # (M, P, 2)
    w = np.where(np.all(np.isfinite(target), axis=-1), w, 0.0)
    w = np.where(w >= MIN_RELATIVE_WEIGHT * w.max(axis=1, keepdims=True), w, 0.0) ** 2  # inverse variance
    target = np.where(w[..., None] > 0, target, 0.0)
    # centred, scaled camera coordinates: the point itself is (0, 0)
    cu = (u - points[:, :1]) / window_px
    cv = (v - points[:, 1:]) / window_px
    result = _fit_local_homography(cu, cv, target, w)
    residual = np.linalg.norm(_apply_homography(result[0], cu, cv) - target, axis=-1)  # (M, P)
    used = w > 0
    masked = np.where(used, residual, np.inf)  # (M, P); unused pixels sort last
    count = used.sum(axis=1)
    ordered = np.sort(masked, axis=1)
    middle = np.clip((count - 1) // 2, 0, masked.shape[1] - 1)
    median = np.where(count > 0, ordered[np.arange(len(points)), middle], 0.0)  # (M,) lower median of used pixels
    keep = used & (residual <= np.maximum(0.5, 4.0 * median)[:, None])
    result = _fit_local_homography(cu, cv, target, np.where(keep, w, 0.0))
    ok = keep.sum(axis=1) >= _MIN_WINDOW_FILL * du.size
    at_point = _apply_homography(result[0], np.zeros((len(points), 1)), np.zeros((len(points), 1)))[:, 0]
    return np.where(ok[:, None], at_point, np.nan), ok


def _fit_local_homography(cu, cv, target, w):
    """Weighted DLT per row: homographies (M, 3, 3) from (cu, cv) (M, P) to target (M, P, 2)."""
    total = np.maximum(w.sum(axis=1, keepdims=True), 1e-12)
    mean = (w[..., None] * target).sum(axis=1) / total  # (M, 2)
    spread = np.sqrt((w * np.sum((target - mean[:, None]) ** 2, axis=-1)).sum(axis=1) / total[:, 0]) + 1e-9
    X = (target[..., 0] - mean[:, :1]) / spread[:, None]  # (M, P)
    Y = (target[..., 1] - mean[:, 1:]) / spread[:, None]
    one, zero = np.ones_like(cu), np.zeros_like(cu)
    rows_x = np.stack([cu, cv, one, zero, zero, zero, -X * cu, -X * cv, -X], axis=-1)  # (M, P, 9)
    rows_y = np.stack([zero, zero, zero, cu, cv, one, -Y * cu, -Y * cv, -Y], axis=-1)
    sqrt_w = np.sqrt(w)[..., None]
    A = np.concatenate([rows_x * sqrt_w, rows_y * sqrt_w], axis=1)  # (M, 2P, 9)
    _, _, vt = np.linalg.svd(A, full_matrices=False)
    H = vt[:, -1, :].reshape(-1, 3, 3)  # normalized target <- (cu, cv)
    denormalize = np.zeros_like(H)
    denormalize[:, 0, 0] = denormalize[:, 1, 1] = spread
    denormalize[:, :2, 2] = mean
    denormalize[:, 2, 2] = 1.0
    return denormalize @ H, mean


def _apply_homography(H, cu, cv):
    """(M, P, 2) images of (cu, cv) (M, P) under per-row homographies H (M, 3, 3)."""
    points = np.stack([cu, cv, np.ones_like(cu)], axis=-1)  # (M, P, 3)
    mapped = np.einsum("mij,mpj->mpi", H, points)
    return mapped[..., :2] / mapped[..., 2:3]


# --------------------------------------------------------------------------------------------------
# Calibration on corner lists
# --------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class DeviceCalibration:
    """One device calibrated by Zhang's method.

    Attributes
    ----------
    device : DeviceModel
        Intrinsics and distortion, ``R = I``, ``T = 0`` (its own frame).
    rms_px : float
        RMS reprojection error over every corner of every view, pixels.
    view_rms_px : ndarray (V,)
        RMS reprojection error of each view, pixels.
    board_poses : list of (R (3, 3), T (3,))
        Board-to-device pose of each view.
    """

    device: DeviceModel
    rms_px: float
    view_rms_px: np.ndarray
    board_poses: list


@dataclass(frozen=True)
class RigCalibration:
    """A calibrated rig and how well it fits.

    Attributes
    ----------
    rig : Rig
        World = camera frame; the projector pose from :func:`refine_relative_pose`.
    camera, projector : DeviceCalibration
        The single-device calibrations.
    relative : RelativePose
        Projector pose in the camera frame with the joint reprojection RMS of both devices.
    names : list of str
        One name per view (e.g. the pose folders), for reports.
    """

    rig: Rig
    camera: DeviceCalibration
    projector: DeviceCalibration
    relative: RelativePose
    names: list

    @property
    def baseline_mm(self) -> float:
        """Distance between the camera and projector optical centres, in the rig's units."""
        return float(np.linalg.norm(self.rig.camera.center - self.rig.projector.center))


def calibrate_device(object_points, image_points, size, *, name: str = "device",
                     fix_k3: bool = True) -> DeviceCalibration:
    """Zhang's calibration of one device (OpenCV ``calibrateCamera``), a camera or a projector.

    Parameters
    ----------
    object_points : list of ndarray (M_k, 3)
        Board points of each view, mm, ``z = 0``.
    image_points : list of ndarray (M_k, 2)
        Their pixels in the device, 0-based.
    size : (int, int)
        Device ``(width, height)`` in pixels.
    name : str
        Names the device in errors.
    fix_k3 : bool
        Keep ``k3 = 0`` (the sixth-order term is poorly determined by a narrow field of view).

    Returns
    -------
    DeviceCalibration

    Notes
    -----
    Skew is 0 (OpenCV's model); ``k1 k2 p1 p2 [k3]`` as in :mod:`dptpu.fpp.distortion`.
    """
    if len(object_points) != len(image_points):
        raise ValueError(f"{name}: need one image point set per object point set; got {len(object_points)} "
                         f"and {len(image_points)}")
    if len(object_points) < 3:
        raise ValueError(f"{name}: Zhang's calibration needs at least 3 board poses; got {len(object_points)}")
    objects = [np.ascontiguousarray(o, dtype=np.float32).reshape(-1, 1, 3) for o in object_points]
    images = [np.ascontiguousarray(p, dtype=np.float32).reshape(-1, 1, 2) for p in image_points]
    for k, (o, p) in enumerate(zip(objects, images)):
        if len(o) != len(p) or len(o) < 6:
            raise ValueError(f"{name}: view {k + 1} must have the same number (>= 6) of object and image points; "
                             f"got {len(o)} and {len(p)}")
    flags = cv2.CALIB_FIX_K3 if fix_k3 else 0
    criteria = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 200, 1e-12)
    size = (int(size[0]), int(size[1]))
    try:
        _, K, dist, rvecs, tvecs = cv2.calibrateCamera(objects, images, size, None, None, flags=flags,
                                                      criteria=criteria)
    except cv2.error as exc:  # degenerate views (e.g. all boards parallel), points outside the image
        raise ValueError(f"{name}: Zhang's calibration failed ({exc.err}); use poses with the board tilted in "
                         f"several directions") from None
    poses, view_rms, squared = [], [], []
    for o, p, rvec, tvec in zip(objects, images, rvecs, tvecs):
        projected, _ = cv2.projectPoints(o, rvec, tvec, K, dist)
        err2 = np.sum((projected.reshape(-1, 2) - p.reshape(-1, 2)) ** 2, axis=1)
        squared.append(err2)
        view_rms.append(np.sqrt(err2.mean()))
        poses.append((cv2.Rodrigues(rvec)[0], np.ravel(tvec).astype(np.float64)))
    device = DeviceModel(K=K, dist=np.ravel(dist)[:5], R=np.eye(3), T=np.zeros(3), size=size)
    return DeviceCalibration(device=device, rms_px=float(np.sqrt(np.concatenate(squared).mean())),
                             view_rms_px=np.array(view_rms), board_poses=poses)


def calibrate_rig(views: CalibrationViews, camera_size, projector_size, *, units: str = "mm",
                  names=None) -> RigCalibration:
    """Calibrate camera, projector and their relative pose from corner observations.

    Parameters
    ----------
    views : CalibrationViews
        Per view: board points (M_k, 3) mm, camera pixels (M_k, 2), projector pixels (M_k, 2).
    camera_size, projector_size : (int, int)
        ``(width, height)`` in pixels.
    units : str
        Unit of the board points (and of the rig's translations).
    names : list of str, optional
        One name per view for reports (default ``view 1``, ``view 2``, ...).

    Returns
    -------
    RigCalibration
        World frame = camera frame.
    """
    n_views = len(views.object_points)
    names = list(names) if names is not None else [f"view {k + 1}" for k in range(n_views)]
    camera = calibrate_device(views.object_points, views.camera_points, camera_size, name="camera")
    projector = calibrate_device(views.object_points, views.projector_points, projector_size, name="projector")
    R_cam, T_cam = camera.board_poses[0]
    R_prj, T_prj = projector.board_poses[0]
    R_start = R_prj @ R_cam.T
    relative = refine_relative_pose(camera.device, projector.device, views,
                                    initial_board_poses=camera.board_poses,
                                    initial_relative=(R_start, T_prj - R_start @ T_cam))
    projector_device = DeviceModel(K=projector.device.K, dist=projector.device.dist, R=relative.R, T=relative.T,
                                   size=projector.device.size)
    rig = Rig(camera=camera.device, projector=projector_device, units=units)
    return RigCalibration(rig=rig, camera=camera, projector=projector, relative=relative, names=names)


# --------------------------------------------------------------------------------------------------
# Calibration poses on disk
# --------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class PoseObservation:
    """The board corners of one calibration pose in the camera and in the projector.

    Attributes
    ----------
    name : str
        The pose folder.
    camera_points : ndarray (M, 2)
        Corner pixels in the camera.
    projector_points : ndarray (M, 2)
        The same corners in the projector, projector pixels.
    camera_size, projector_size : (int, int)
        ``(width, height)`` of the devices.
    corner_ok : ndarray (cols*rows,) bool
        Which of the board's corners are kept (valid phase around them), in :meth:`Board.object_points` order.
    """

    name: str
    camera_points: np.ndarray
    projector_points: np.ndarray
    camera_size: tuple
    projector_size: tuple
    corner_ok: np.ndarray


def find_pose_folders(paths) -> list[Path]:
    """Expand the command line's folders into pose folders (each holding ``x/`` and ``y/`` captures).

    A folder that holds ``x/`` and ``y/`` is a pose; a folder that holds none, but whose sub-folders are
    poses, stands for those sub-folders in name order (``dptpu calibrate calib/``).

    Raises
    ------
    FileNotFoundError
        A path does not exist.
    ValueError
        A folder is neither a pose nor a folder of poses.
    """
    poses = []
    for path in map(Path, paths):
        if not path.is_dir():
            raise FileNotFoundError(f"{path}: no such calibration pose folder")
        if _is_pose(path):
            poses.append(path)
            continue
        children = sorted(p for p in path.iterdir() if p.is_dir() and _is_pose(p))
        if not children:
            raise ValueError(f"{path}: not a calibration pose (a folder with the captures x/ and y/, fringe_axis "
                             f"x and y; docs/calibration.md) nor a folder of poses")
        poses.extend(children)
    return poses


def _is_pose(path: Path) -> bool:
    return all((path / axis / "capture.yaml").is_file() for axis in _AXES)


def observe_pose(folder, board: Board, *, window_px: int = 6) -> PoseObservation:
    """Board corners of one pose folder in the camera and the projector (steps 1-2 of the module docstring).

    Parameters
    ----------
    folder : path-like
        A pose folder: ``x/`` and ``y/`` ``dptpu-capture/1`` folders with ``fringe_axis`` x and y.
    board : Board
    window_px : int
        Half-size of the window of the local homographies (:func:`projector_points_at`).

    Raises
    ------
    ValueError
        Naming the folder: a capture has the wrong ``fringe_axis``, the captures' camera or projector sizes
        differ, the board is not found, or fewer than 80 % of the corners have a valid phase around them.
    """
    folder = Path(folder)
    captures = {}
    for axis in _AXES:
        path = folder / axis
        if not (path / "capture.yaml").is_file():
            raise FileNotFoundError(f"{folder}: missing the capture {axis}/ (a pose holds x/ and y/ captures)")
        capture = read_capture(path)
        if capture.fringe_axis != axis:
            raise ValueError(f"{path}: fringe_axis must be {axis!r} in the {axis}/ capture of a pose; got "
                             f"{capture.fringe_axis!r}")
        captures[axis] = capture
    for key in ("camera_size", "projector_size"):
        a, b = getattr(captures["x"], key), getattr(captures["y"], key)
        if tuple(a) != tuple(b):
            raise ValueError(f"{folder}: x/ and y/ captures must have the same {key.replace('_', '.')}; got "
                             f"{a[0]}x{a[1]} and {b[0]}x{b[1]}")
    results = {axis: _absolute_phase(capture) for axis, capture in captures.items()}
    image = load_reference(captures["x"], "white")
    if image is None:
        image = load_reference(captures["y"], "white")
    if image is None:
        image = results["x"][1]  # fringe average A of the highest x sequence
    corners = find_board_corners(image, board, where=str(folder))
    coordinate = []
    for axis in _AXES:
        result = results[axis][0]
        coordinate.append(result.absolute_phase * result.fringe_extent_px / (2.0 * np.pi * result.frequency))
    projector_xy = np.stack(coordinate, axis=-1)  # (H, W, 2)
    valid = results["x"][0].valid & results["y"][0].valid
    weights = np.where(valid, np.minimum(results["x"][0].modulation, results["y"][0].modulation), 0.0)
    projector, ok = projector_points_at(corners, projector_xy, weights, window_px=window_px)
    if ok.mean() < 0.8:
        raise ValueError(f"{folder}: only {int(ok.sum())} of {ok.size} board corners have a valid phase around them "
                         f"in both x/ and y/ (is the board lit by the projector? too dark?)")
    return PoseObservation(name=str(folder), camera_points=corners[ok], projector_points=projector[ok],
                           camera_size=tuple(captures["x"].camera_size),
                           projector_size=tuple(captures["x"].projector_size), corner_ok=ok)


def _absolute_phase(capture: Capture) -> tuple[CaptureResult, np.ndarray]:
    """Absolute phase of a calibration capture (mf when it has an ``f <= 1`` sequence, else heterodyne), and
    the fringe average (H, W) of its highest-frequency sequence."""
    frequencies = [capture.frequency_of(s) for s in capture.phase_sequences]
    if len(frequencies) < 2:
        raise ValueError(f"{capture.root}: a calibration capture needs two or more phase sequences (e.g. f and 1); "
                         f"got {len(frequencies)}")
    method = "mf" if min(frequencies) <= 1.0 + 1e-9 else "heterodyne"
    # the board's black squares have low modulation: accept 1 % of full scale, weight by modulation later
    result = unwrap_capture(capture, method=method, min_modulation=0.01 * (2 ** capture.bit_depth - 1))
    return result, _fringe_average(capture)


def _fringe_average(capture: Capture) -> np.ndarray:
    highest = max(capture.phase_sequences, key=capture.frequency_of)
    return load_sequence_images(capture, highest).astype(np.float64).mean(axis=0)


def calibrate_from_folders(paths, board: Board, *, window_px: int = 6, progress: bool = False) -> RigCalibration:
    """Calibrate a rig from calibration pose folders (real or twin; docs/calibration.md).

    Parameters
    ----------
    paths : list of path-like
        Pose folders, or folders of pose folders (:func:`find_pose_folders`); at least 3 poses.
    board : Board
    window_px : int
        Half-size of the local-homography window, camera pixels.
    progress : bool
        A tqdm bar over the poses on stderr.

    Returns
    -------
    RigCalibration
        World = camera frame, units mm.

    Raises
    ------
    ValueError
        Fewer than 3 poses; a pose's problem (see :func:`observe_pose`) naming its folder; poses whose camera
        or projector sizes differ.
    """
    folders = find_pose_folders(paths)
    if len(folders) < 3:
        raise ValueError(f"calibration needs at least 3 board poses; got {len(folders)} "
                         f"({', '.join(map(str, folders)) or 'none'})")
    observations: list[PoseObservation] = []
    object_points = []
    for folder in tqdm(folders, desc="observing poses", unit="pose", disable=not progress, file=sys.stderr):
        observation = observe_pose(folder, board, window_px=window_px)
        first = observations[0] if observations else observation
        for key in ("camera_size", "projector_size"):
            if getattr(observation, key) != getattr(first, key):
                a, b = getattr(first, key), getattr(observation, key)
                raise ValueError(f"{folder}: {key.replace('_', ' ')} {b[0]}x{b[1]} differs from {a[0]}x{a[1]} of "
                                 f"{first.name}; all poses must come from one rig")
        observations.append(observation)
        object_points.append(board.object_points()[observation.corner_ok])
    views = CalibrationViews(object_points=object_points,
                             camera_points=[o.camera_points for o in observations],
                             projector_points=[o.projector_points for o in observations])
    return calibrate_rig(views, observations[0].camera_size, observations[0].projector_size, units="mm",
                         names=[o.name for o in observations])
