"""Hand-eye calibration in the twin: a known mounting, robot poses that show the board, rendered board views.

1. :func:`random_mounting`: a mount ``X`` and a board place ``Y`` for a setup (:mod:`dptpu.fpp.hand_eye`'s
   frames): eye-in-hand, the camera 40..120 mm off the flange, turned anyhow, the board somewhere before the robot;
   eye-to-hand, the camera 0.6..1.2 m from the base, the board 50..150 mm off the flange.
2. :func:`hand_eye_views`: ``count`` board poses in the camera's view (:func:`dptpu.sim.calibrate.board_poses`:
   tilts of 20..40 degrees in directions all around, so the robot's rotation axes differ) and the flange pose of
   each, ``base_T_flange = Y B^-1 X^-1`` (eye-in-hand) or ``X B Y^-1`` (eye-to-hand), exact.
3. :func:`render_board_views`: the board's white image of each view, ``supersample`` x ``supersample`` rays per
   pixel binned (as :mod:`dptpu.sim.calibrate` does), then Gaussian camera noise of ``noise_dn`` gray levels per
   pixel (the paper's 1 sigma is 1.5693; docs/dataset.md), quantized to 8 bits.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from dptpu.fpp.calibration import Rig
from dptpu.fpp.hand_eye import SETUPS, invert, rigid
from dptpu.fpp.rig_calibration import Board

from .calibrate import board_poses
from .image_formation import SequenceSpec, quantize, render_frames_float
from .raycast import trace
from .rig import resize_camera
from .scenes import board_scene

__all__ = ["PAPER_NOISE_1_SIGMA_DN", "flange_poses", "hand_eye_views", "random_mounting", "render_board_views"]

#: The paper's 1 sigma camera noise, gray levels (docs/dataset.md).
PAPER_NOISE_1_SIGMA_DN = 1.5693


def random_mounting(setup: str, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A random mount ``X`` and board place ``Y`` (4x4, metres) for ``setup`` (module docstring)."""
    if setup not in SETUPS:
        raise ValueError(f"setup must be one of {', '.join(SETUPS)}; got {setup!r}")
    direction = rng.normal(size=3)
    direction /= np.linalg.norm(direction)
    if setup == "eye-in-hand":
        X = rigid(Rotation.random(random_state=rng).as_matrix(), direction * rng.uniform(0.04, 0.12))
        Y = rigid(Rotation.random(random_state=rng).as_matrix(), [rng.uniform(0.4, 0.8), rng.uniform(-0.3, 0.3),
                                                                   rng.uniform(-0.2, 0.2)])
    else:
        X = rigid(Rotation.random(random_state=rng).as_matrix(), direction * rng.uniform(0.6, 1.2))
        Y = rigid(Rotation.random(random_state=rng).as_matrix(), -direction * rng.uniform(0.05, 0.15))
    return X, Y


def hand_eye_views(rig: Rig, board: Board, *, setup: str, mount: np.ndarray, board_place: np.ndarray, count: int,
                   seed: int = 0) -> tuple[list[np.ndarray], list[tuple[np.ndarray, np.ndarray]]]:
    """Flange poses (``base_T_flange``, metres) and the board's world poses of ``count`` views (module docstring).

    Returns
    -------
    (list of ndarray (4, 4), list of (R (3, 3), T (3,)))
        The robot's flange poses, and the board-to-world poses in the rig's frame and units
        (:func:`dptpu.sim.calibrate.board_poses`, what :func:`render_board_views` renders).
    """
    world_poses = board_poses(rig, board, count, seed=seed)
    return flange_poses(rig, world_poses, setup=setup, mount=mount, board_place=board_place), world_poses


def flange_poses(rig: Rig, world_poses, *, setup: str, mount: np.ndarray, board_place: np.ndarray) -> list[np.ndarray]:
    """``base_T_flange`` (4x4, metres) at which the camera sees the board at each of ``world_poses`` (board-to-world
    ``(R, T)`` in the rig's frame and units), for the mount ``X`` and board place ``Y`` of ``setup``."""
    if setup not in SETUPS:
        raise ValueError(f"setup must be one of {', '.join(SETUPS)}; got {setup!r}")
    scale = rig.scale_to_m
    flange = []
    for R, T in world_poses:
        # the board in the camera optical frame: X_cam = R_c (R X_board + T) + T_c, in metres
        B = rigid(rig.camera.R @ R, (rig.camera.R @ T + rig.camera.T) * scale)
        if setup == "eye-in-hand":
            flange.append(board_place @ invert(B) @ invert(mount))
        else:
            flange.append(mount @ B @ invert(board_place))
    return flange


def render_board_views(rig: Rig, board: Board, world_poses, *, noise_dn: float = PAPER_NOISE_1_SIGMA_DN,
                       supersample: int = 2, seed: int = 0) -> list[np.ndarray]:
    """The white image (H, W) uint8 of the board at each of ``world_poses`` (module docstring)."""
    if int(supersample) < 1:
        raise ValueError(f"supersample must be an integer >= 1; got {supersample!r}")
    if not noise_dn >= 0:
        raise ValueError(f"noise_dn must be >= 0 gray levels; got {noise_dn}")
    s = int(supersample)
    width, height = rig.camera.size
    fine = resize_camera(rig, (width * s, height * s)) if s > 1 else rig
    rng = np.random.default_rng(seed)
    images = []
    for R, T in world_poses:
        scene = board_scene(fine, R, T, cols=board.cols, rows=board.rows, square_mm=board.square_mm)
        (white,) = render_frames_float(fine, trace(fine, scene), [SequenceSpec(kind="white")], effects=[])
        binned = white[0].reshape(height, s, width, s).mean(axis=(1, 3))  # (H, W) gray levels
        images.append(quantize(binned + rng.normal(0.0, noise_dn, binned.shape)))
    return images
