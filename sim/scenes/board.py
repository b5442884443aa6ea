"""Calibration boards: a textured checkerboard plane whose inner corners sit at known world points."""
from __future__ import annotations

import numpy as np

from dptpu.fpp.calibration import Rig
from dptpu.sim.scene_mesh import Material

from .scene import Scene, posed_mesh

__all__ = ["board_scene", "board_corners", "checker_texture", "TEXELS_PER_SQUARE", "BLACK_ALBEDO"]

#: Texture resolution of one board square (texels along an edge).
TEXELS_PER_SQUARE = 64
#: Reflectance of the dark squares (the light squares take the material's albedo).
BLACK_ALBEDO = 0.05


def board_corners(cols: int, rows: int, square_mm: float) -> np.ndarray:
    """Inner corners in the board frame, (rows*cols, 3): ``(i*square, j*square, 0)``, ``i`` fastest (OpenCV's
    ``findChessboardCorners`` order for ``patternSize = (cols, rows)``)."""
    j, i = np.mgrid[0:rows, 0:cols]
    return np.stack([i.ravel() * square_mm, j.ravel() * square_mm, np.zeros(rows * cols)], axis=1).astype(float)


def checker_texture(cols: int, rows: int, *, margin_squares: int = 1) -> np.ndarray:
    """Albedo factor texture (Ht, Wt) float32 of a board of ``(cols+1) x (rows+1)`` squares plus a white margin of
    ``margin_squares``; the square touching the first inner corner's top-left is dark."""
    squares_x, squares_y = cols + 1, rows + 1
    total_x, total_y = squares_x + 2 * margin_squares, squares_y + 2 * margin_squares
    ty, tx = np.mgrid[0:total_y * TEXELS_PER_SQUARE, 0:total_x * TEXELS_PER_SQUARE]
    sx, sy = tx // TEXELS_PER_SQUARE - margin_squares, ty // TEXELS_PER_SQUARE - margin_squares
    inside = (sx >= 0) & (sx < squares_x) & (sy >= 0) & (sy < squares_y)
    dark = inside & ((sx + sy) % 2 == 0)
    return np.where(dark, BLACK_ALBEDO, 1.0).astype(np.float32)


def board_scene(rig: Rig, pose_R, pose_T, *, cols: int = 11, rows: int = 8, square_mm: float = 12.0,
                margin_squares: int = 1, material: Material | None = None) -> Scene:
    """A checkerboard plane posed by ``X_world = pose_R @ X_board + pose_T``.

    Parameters
    ----------
    rig : Rig
        Only for its units (the board is built in the rig's units; ``square_mm`` is in those units).
    pose_R : ndarray (3, 3)
        Board -> world rotation.
    pose_T : ndarray (3,)
        Board -> world translation: the world position of the first inner corner.
    cols, rows : int
        Inner corners per row and per column (OpenCV ``patternSize = (cols, rows)``); the board has
        ``(cols+1) x (rows+1)`` squares and a light margin of ``margin_squares``.
    square_mm : float
        Square edge, rig units.

    Returns
    -------
    Scene
        One textured mesh (``albedo_texture`` + ``uv``: light squares reflect the material albedo, dark squares
        :data:`BLACK_ALBEDO` times it); ``landmarks["board_corners"]`` holds the inner corners in world
        coordinates, (rows*cols, 3), in OpenCV order; ``landmarks["board_corners_board"]`` the same in the board
        frame.

    Convention: board frame x along a row of corners, y down the columns, z = 0 on the board surface, the board
    normal is -z (its printed face looks along -z, towards a camera in front of it).
    """
    if int(cols) < 2 or int(rows) < 2 or not square_mm > 0:
        raise ValueError(f"board needs cols, rows >= 2 and square_mm > 0; got {cols}, {rows}, {square_mm}")
    cols, rows = int(cols), int(rows)
    R = np.asarray(pose_R, dtype=np.float64).reshape(3, 3)
    T = np.asarray(pose_T, dtype=np.float64).reshape(3)
    s = float(square_mm)
    x0, y0 = -(1 + margin_squares) * s, -(1 + margin_squares) * s
    x1, y1 = (cols + margin_squares) * s, (rows + margin_squares) * s
    vertices = np.array([[x0, y0, 0.0], [x1, y0, 0.0], [x1, y1, 0.0], [x0, y1, 0.0]])
    uv = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    triangles = np.array([[0, 2, 1], [0, 3, 2]])  # normal -z
    texture = checker_texture(cols, rows, margin_squares=margin_squares)
    mesh = posed_mesh("board", vertices, triangles, rotation=R, translation=T,
                      material=material or Material(albedo=0.9, roughness=0.9, specular=0.0, ior=1.5),
                      albedo_texture=texture, uv=uv)
    corners_board = board_corners(cols, rows, s)
    return Scene(meshes=[mesh], name=f"board-{cols}x{rows}", source=f"board({cols}x{rows}, {s:g} {rig.units})",
                 landmarks={"board_corners": corners_board @ R.T + T, "board_corners_board": corners_board})
