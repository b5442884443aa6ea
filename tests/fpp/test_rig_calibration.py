"""Rig calibration (Zhang + projector as an inverse camera) on analytic observations of a checkerboard.

Board poses are projected through a known rig (tests/fpp/rig_fixtures.py) with exact ray-plane geometry and the
lens model of dptpu.fpp.distortion, so every expected value is analytic.
"""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from dptpu.fpp.calibration import DeviceModel, Rig, load_rig
from dptpu.fpp.capture import PhaseFrames, write_capture
from dptpu.fpp.distortion import pixels_to_normalized, undistort
from dptpu.fpp.rig_calibration import (
    Board,
    calibrate_from_folders,
    calibrate_rig,
    find_board_corners,
    find_pose_folders,
    parse_board,
    projector_points_at,
)
from dptpu.fpp.stereo_calibration import CalibrationViews, project

from .rig_fixtures import synthetic_rig

BOARD = Board(10, 8, 13.0)  # nearly fills the narrow (~14 degree) view: focal errors < 0.3 % (measured)
SIZE = (320, 240)


def _rig(distortion=True) -> Rig:
    return synthetic_rig(distortion=distortion, camera_size=SIZE)


def _board_poses(count, seed=0, rig=None):
    """Board-to-camera poses (R, T): tilted 20..40 degrees all around, 780..900 mm away, whole board in view."""
    rng = np.random.default_rng(seed)
    rig = rig or _rig()
    centre = np.array([(BOARD.cols - 1) / 2, (BOARD.rows - 1) / 2, 0.0]) * BOARD.square_mm
    margin = 1.3 * BOARD.square_mm  # the outer squares and a thin white border must be in view too
    right, bottom = (BOARD.cols - 1) * BOARD.square_mm + margin, (BOARD.rows - 1) * BOARD.square_mm + margin
    outline = np.array([[-margin, -margin, 0], [right, -margin, 0], [-margin, bottom, 0], [right, bottom, 0]])
    poses = []
    for _ in range(100 * count):
        if len(poses) == count:
            break
        k = len(poses)
        angle = np.radians(40.0) * (0.5 + 0.5 * rng.random())
        direction = 2 * np.pi * k / count + 0.3 * rng.random()
        tilt = Rotation.from_rotvec(angle * np.array([np.cos(direction), np.sin(direction), 0.0]))
        spin = Rotation.from_rotvec([0, 0, np.radians(rng.uniform(-15, 15))])
        R = (tilt * spin).as_matrix()
        T = np.array([rng.uniform(-8, 8), rng.uniform(-6, 6), rng.uniform(780, 900)]) - R @ centre
        corners = project(rig.camera, outline @ R.T + T)
        if corners.min() >= 0 and np.all(corners.max(axis=0) <= np.array(SIZE) - 1):
            poses.append((R, T))
    assert len(poses) == count, "board poses: the board does not fit the view"
    return poses


def _rays(device: DeviceModel, shape):
    """Unit-depth ray directions (H, W, 3) of every pixel, in the device frame (lens distortion removed)."""
    v, u = np.mgrid[0:shape[0], 0:shape[1]].astype(np.float64)
    xy = undistort(pixels_to_normalized(np.stack([u, v], axis=-1), device.K), device.dist)
    return np.concatenate([xy, np.ones(shape + (1,))], axis=-1)


def _board_hits(rig: Rig, R, T, shape, supersample=1):
    """Camera-frame points (H*s, W*s, 3) where pixel rays (on an s x s sub-grid) meet the board plane."""
    camera = rig.camera
    s = supersample
    v, u = np.mgrid[0:shape[0] * s, 0:shape[1] * s].astype(np.float64)
    uv = np.stack([(u + 0.5) / s - 0.5, (v + 0.5) / s - 0.5], axis=-1)
    xy = undistort(pixels_to_normalized(uv, camera.K), camera.dist)
    rays = np.concatenate([xy, np.ones(xy.shape[:2] + (1,))], axis=-1)
    normal = R[:, 2]
    depth = (normal @ T) / (rays @ normal)
    return rays * depth[..., None]


def _checker_albedo(points_camera, R, T):
    """Albedo 0.1 (black) / 0.9 (white) of the board at camera-frame points; white margin around the squares."""
    board_xy = (points_camera - T) @ R  # board frame
    i = np.floor(board_xy[..., 0] / BOARD.square_mm)
    j = np.floor(board_xy[..., 1] / BOARD.square_mm)
    inside = (i >= -1) & (i < BOARD.cols) & (j >= -1) & (j < BOARD.rows)
    black = inside & ((i + j) % 2 == 0)
    return np.where(black, 0.1, 0.9)


def _corner_pixels(rig: Rig, R, T):
    """Exact camera and projector pixels (M, 2) of the board's inner corners."""
    in_camera = BOARD.object_points() @ R.T + T
    in_projector = in_camera @ rig.projector.R.T + rig.projector.T
    return project(rig.camera, in_camera), project(rig.projector, in_projector)


def _projector_map(rig: Rig, hits):
    return project(rig.projector, (hits.reshape(-1, 3) @ rig.projector.R.T + rig.projector.T)).reshape(
        hits.shape[:2] + (2,))


# --- board spec --------------------------------------------------------------------------------------------

def test_parse_board_reads_cols_rows_and_square():
    board = parse_board("9x6:15.5")
    assert (board.cols, board.rows, board.square_mm) == (9, 6, 15.5)
    points = board.object_points()
    assert points.shape == (54, 3)
    np.testing.assert_allclose(points[10], [15.5, 15.5, 0.0])  # column 1, row 1


@pytest.mark.parametrize("text", ["9x6", "9-6:15", "2x6:15", "9x6:0", "axb:c"])
def test_parse_board_rejects_bad_text(text):
    with pytest.raises(ValueError, match="board"):
        parse_board(text)


# --- corners -----------------------------------------------------------------------------------------------

def test_find_board_corners_matches_projected_corners():
    rig = _rig()
    R, T = _board_poses(4)[1]
    shape = (SIZE[1], SIZE[0])
    hits = _board_hits(rig, R, T, shape, supersample=4)
    albedo = _checker_albedo(hits, R, T).reshape(shape[0], 4, shape[1], 4).mean(axis=(1, 3))
    image = np.rint(10 + 230 * albedo).astype(np.uint8)
    corners = find_board_corners(image, BOARD)
    expected, _ = _corner_pixels(rig, R, T)
    # findChessboardCorners may list the corners from either end of a symmetric board
    if np.abs(corners[::-1] - expected).max() < np.abs(corners - expected).max():
        corners = corners[::-1]
    error = np.linalg.norm(corners - expected, axis=1)
    # cornerSubPix on an anti-aliased, foreshortened 320x240 board: ~0.1 px (measured 0.11 RMS, 0.18 max)
    assert np.sqrt(np.mean(error ** 2)) < 0.15 and error.max() < 0.3


def test_find_board_corners_names_the_image_when_no_board():
    with pytest.raises(ValueError, match="pose_07: no 10x8 checkerboard corners found"):
        find_board_corners(np.full((240, 320), 128, np.uint8), BOARD, where="pose_07")


def test_projector_points_at_recovers_analytic_projector_corners():
    rig = _rig()
    R, T = _board_poses(4)[2]
    shape = (SIZE[1], SIZE[0])
    hits = _board_hits(rig, R, T, shape)
    projector_xy = _projector_map(rig, hits)  # (H, W, 2) exact
    camera_px, projector_px = _corner_pixels(rig, R, T)
    weights = _checker_albedo(hits, R, T)
    found, ok = projector_points_at(camera_px, projector_xy, weights)
    assert ok.all()
    assert np.abs(found - projector_px).max() < 0.01  # projector pixels


def test_projector_points_at_ignores_a_wrong_fringe_order_and_flags_empty_windows():
    rig = _rig()
    R, T = _board_poses(4)[0]
    shape = (SIZE[1], SIZE[0])
    hits = _board_hits(rig, R, T, shape)
    projector_xy = _projector_map(rig, hits)
    camera_px, projector_px = _corner_pixels(rig, R, T)
    u, v = np.rint(camera_px[5]).astype(int)
    projector_xy[v - 1:v + 2, u - 1:u + 2, 0] += 912 / 16  # one period off: a wrong order
    weights = np.ones(shape)
    u, v = np.rint(camera_px[9]).astype(int)
    weights[v - 8:v + 9, u - 8:u + 9] = 0.0  # no valid phase around corner 9
    found, ok = projector_points_at(camera_px, projector_xy, weights)
    assert not ok[9] and np.isnan(found[9]).all()
    assert np.abs(found[ok] - projector_px[ok]).max() < 0.01


# --- calibration -------------------------------------------------------------------------------------------

def test_calibrate_rig_recovers_intrinsics_and_baseline_from_noisy_corners():
    rig = _rig()
    rng = np.random.default_rng(1)
    objects, cams, prjs = [], [], []
    for R, T in _board_poses(10):
        camera_px, projector_px = _corner_pixels(rig, R, T)
        objects.append(BOARD.object_points())
        cams.append(camera_px + rng.normal(0, 0.05, camera_px.shape))
        prjs.append(projector_px + rng.normal(0, 0.05, projector_px.shape))
    result = calibrate_rig(CalibrationViews(objects, cams, prjs), SIZE, (912, 1140))
    for estimated, true in ((result.rig.camera, rig.camera), (result.rig.projector, rig.projector)):
        np.testing.assert_allclose(np.diag(estimated.K)[:2], np.diag(true.K)[:2], rtol=5e-3)  # the bound
    true_baseline = np.linalg.norm(rig.camera.center - rig.projector.center)
    assert abs(result.baseline_mm - true_baseline) < 0.5
    R_true = rig.projector.R @ rig.camera.R.T
    angle = np.degrees(np.linalg.norm(Rotation.from_matrix(result.rig.projector.R @ R_true.T).as_rotvec()))
    assert angle < 0.5  # a few pixels of principal point (1 px = 0.04 degrees)
    assert result.camera.rms_px < 0.1 and result.relative.rms_projector_px < 0.1  # ~ the 0.05 px noise
    np.testing.assert_array_equal(result.rig.camera.R, np.eye(3))  # world = camera frame


# --- pose folders ------------------------------------------------------------------------------------------

def _write_pose(folder, rig, R, T, *, frequencies=(16, 1), steps=4, camera_shape=None, supersample=3):
    """A calibration pose folder: x/ and y/ captures of fringes on the board (analytic image formation; each
    pixel integrates ``supersample`` x ``supersample`` rays, as a sensor integrates over its area)."""
    shape = camera_shape or (SIZE[1], SIZE[0])
    s = supersample
    hits = _board_hits(rig, R, T, shape, supersample=s)
    albedo = _checker_albedo(hits, R, T)  # (H*s, W*s)
    projector_xy = _projector_map(rig, hits)

    def pixels(levels):  # (..., H*s, W*s) -> (..., H, W) uint8
        binned = levels.reshape(levels.shape[:-2] + (shape[0], s, shape[1], s)).mean(axis=(-3, -1))
        return np.clip(np.rint(binned), 0, 255).astype(np.uint8)

    projector_size = rig.projector.size
    for index, axis in enumerate(("x", "y")):
        extent = projector_size[index]
        sequences = []
        for f in frequencies:
            phase = 2 * np.pi * f * projector_xy[..., index] / extent
            n = np.arange(steps)[:, None, None]
            levels = 12 + 220 * albedo * (0.5 + 0.45 * np.cos(phase - 2 * np.pi * n / steps))
            sequences.append(PhaseFrames(images=pixels(levels), frequency=f))
        white = pixels(12 + 220 * albedo * 0.95)
        write_capture(folder / axis, sequences=sequences, projector_size=projector_size, fringe_axis=axis,
                      references={"white": white})


def test_calibrate_from_folders_recovers_the_rig_and_the_rig_file_round_trips(tmp_path):
    from dptpu.fpp.calibration import save_rig

    rig = _rig()
    for k, (R, T) in enumerate(_board_poses(6)):
        _write_pose(tmp_path / "calib" / f"pose_{k:02d}", rig, R, T, supersample=2)
    result = calibrate_from_folders([tmp_path / "calib"], BOARD)
    assert len(result.names) == 6 and result.names[0].endswith("pose_00")
    for estimated, true in ((result.rig.camera, rig.camera), (result.rig.projector, rig.projector)):
        np.testing.assert_allclose(np.diag(estimated.K)[:2], np.diag(true.K)[:2], rtol=5e-3)
    true_baseline = np.linalg.norm(rig.camera.center - rig.projector.center)
    assert abs(result.baseline_mm - true_baseline) < 1.0
    assert result.camera.rms_px < 0.2 and result.projector.rms_px < 0.3
    back = load_rig(save_rig(result.rig, tmp_path / "rig.yaml"))
    np.testing.assert_allclose(back.projector.T, result.rig.projector.T)


def test_calibrate_from_folders_names_the_pose_without_a_board(tmp_path):
    rig = _rig()
    poses = _board_poses(3)
    poses[1] = (poses[1][0], poses[1][1] + [500.0, 0.0, 0.0])  # the board out of view: a plain white wall
    for k, (R, T) in enumerate(poses):
        _write_pose(tmp_path / f"pose_{k}", rig, R, T, supersample=1)
    with pytest.raises(ValueError, match=r"pose_1: no 10x8 checkerboard corners"):
        calibrate_from_folders([tmp_path / f"pose_{k}" for k in range(3)], BOARD)


def test_calibrate_from_folders_rejects_mismatched_sizes_naming_the_folder(tmp_path):
    rig = _rig()
    poses = _board_poses(3)
    for k in range(3):
        _write_pose(tmp_path / f"pose_{k}", rig, *poses[k], supersample=1)
    # replace pose_2's y capture with a smaller camera
    import shutil

    shutil.rmtree(tmp_path / "pose_2" / "y")
    small = Rig(camera=DeviceModel(K=rig.camera.K, dist=rig.camera.dist, R=rig.camera.R, T=rig.camera.T,
                                   size=(300, 240)), projector=rig.projector)
    _write_pose(tmp_path / "tmp", small, *poses[2], camera_shape=(240, 300), supersample=1)
    shutil.move(tmp_path / "tmp" / "y", tmp_path / "pose_2" / "y")
    with pytest.raises(ValueError, match=r"pose_2: x/ and y/ captures must have the same camera.size"):
        calibrate_from_folders([tmp_path / f"pose_{k}" for k in range(3)], BOARD)


def test_find_pose_folders_rejects_a_folder_without_captures(tmp_path):
    (tmp_path / "empty").mkdir()
    with pytest.raises(ValueError, match="empty: not a calibration pose"):
        find_pose_folders([tmp_path / "empty"])
    with pytest.raises(FileNotFoundError, match="missing: no such calibration pose folder"):
        find_pose_folders([tmp_path / "missing"])


def test_calibrate_device_turns_degenerate_views_into_a_clear_error():
    from dptpu.fpp.rig_calibration import calibrate_device

    board = Board(4, 3, 10.0)
    flat = board.object_points()[:, :2] * 5 + 100  # three identical fronto-parallel views: no focal length
    with pytest.raises(ValueError, match="camera: Zhang's calibration failed"):
        calibrate_device([board.object_points()] * 3, [flat] * 3, (320, 240), name="camera")
    with pytest.raises(ValueError, match="projector: Zhang's calibration needs at least 3 board poses; got 2"):
        calibrate_device([board.object_points()] * 2, [flat] * 2, (912, 1140), name="projector")
