"""Built-in scenes, usable by name: ``sphere``, ``plane``, ``board``."""
from __future__ import annotations

from collections.abc import Callable

import numpy as np

from dptpu.fpp.calibration import Rig
from dptpu.sim.rig import working_point
from dptpu.sim.scene_mesh import Material

from . import primitives
from .board import board_scene
from .scene import Scene, posed_mesh

__all__ = ["BUILTIN_SCENES", "STANDARD_SPHERE_DIAMETER_MM", "sphere_scene", "plane_scene", "default_board_scene"]

#: The DP-TPU standard ceramic sphere (paper, Fig. 3).
STANDARD_SPHERE_DIAMETER_MM = 50.8082


def _mm(rig: Rig) -> float:
    """One millimetre in the rig's units."""
    return 1e-3 / rig.scale_to_m


def sphere_scene(rig: Rig, *, center=None, diameter_mm: float = STANDARD_SPHERE_DIAMETER_MM,
                 subdivisions: int = 6, material: Material | None = None) -> Scene:
    """The standard sphere (diameter 50.8082 mm) at ``center`` (world, default the rig's working point, on both
    optical axes so camera and projector see it). ``landmarks``: ``sphere_center`` (3,), ``sphere_radius`` ()."""
    center = working_point(rig) if center is None else np.asarray(center, dtype=np.float64).reshape(3)
    radius = diameter_mm / 2.0 * _mm(rig)
    vertices, triangles = primitives.sphere(radius, subdivisions)
    mesh = posed_mesh("sphere", vertices, triangles, translation=center,
                      material=material or Material(albedo=0.8, roughness=0.5, specular=0.1, ior=1.6))
    return Scene(meshes=[mesh], name="sphere", source="builtin:sphere",
                 landmarks={"sphere_center": center, "sphere_radius": np.float64(radius)})


def plane_scene(rig: Rig, *, distance=None, material: Material | None = None) -> Scene:
    """A plane facing the camera (normal along the camera's -z) at the working distance (or ``distance`` along
    the camera axis), large enough to fill the camera's view."""
    point = working_point(rig)
    R_cw = rig.camera.R.T
    axis = R_cw[:, 2]
    if distance is not None:
        point = rig.camera.center + axis * float(distance)
    depth = float(axis @ (point - rig.camera.center))
    width, height = rig.camera.size
    fov_x = width / rig.camera.K[0, 0] * depth
    fov_y = height / rig.camera.K[1, 1] * depth
    vertices, triangles, uv = primitives.plane((2.0 * fov_x, 2.0 * fov_y), 1)
    centre = rig.camera.center + axis * depth
    mesh = posed_mesh("plane", vertices, triangles, rotation=R_cw, translation=centre,
                      material=material or Material(albedo=0.8, roughness=0.9, specular=0.0, ior=1.5))
    return Scene(meshes=[mesh], name="plane", source="builtin:plane",
                 landmarks={"plane_point": centre, "plane_normal": -axis})


def default_board_scene(rig: Rig, *, cols: int = 11, rows: int = 8, square_mm: float = 12.0) -> Scene:
    """A board facing the camera, centred on the working point, its rows along the camera's x."""
    R = rig.camera.R.T  # board axes = camera axes
    s = square_mm * _mm(rig)
    centre_board = np.array([(cols - 1) * s / 2.0, (rows - 1) * s / 2.0, 0.0])
    T = working_point(rig) - R @ centre_board
    return board_scene(rig, R, T, cols=cols, rows=rows, square_mm=s)


BUILTIN_SCENES: dict[str, Callable[[Rig], Scene]] = {"sphere": sphere_scene, "plane": plane_scene,
                                                    "board": default_board_scene}
