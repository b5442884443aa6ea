"""A scene of the twin: a list of :class:`~dptpu.sim.scene_mesh.SceneMesh` in the rig's world frame, and how
objects are posed there."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from dptpu.sim.scene_mesh import Material, SceneMesh

__all__ = ["Scene", "euler_xyz_deg", "look_at_rotation", "posed_mesh"]


@dataclass(frozen=True)
class Scene:
    """What a renderer draws.

    Attributes
    ----------
    meshes : list of SceneMesh
        Objects in the rig's world frame and units.
    name : str
        Scene name (built-in name, file stem, ``random-<seed>``).
    source : str
        Where it came from (file path, ``builtin:sphere``, ``random(seed=3)``).
    landmarks : dict of str -> ndarray
        Known 3D points in world coordinates, e.g. ``board_corners`` (rows*cols, 3) of a calibration board or
        ``sphere_center`` (3,).
    """

    meshes: list
    name: str = "scene"
    source: str = ""
    landmarks: dict = field(default_factory=dict)

    def __post_init__(self):
        meshes = list(self.meshes)
        if not meshes:
            raise ValueError(f"scene {self.name!r}: needs at least one mesh")
        for i, mesh in enumerate(meshes):
            if not isinstance(mesh, SceneMesh):
                raise ValueError(f"scene {self.name!r}: meshes[{i}] must be a SceneMesh; got {type(mesh).__name__}")
        object.__setattr__(self, "meshes", meshes)


def euler_xyz_deg(angles_deg) -> np.ndarray:
    """Rotation (3, 3) of extrinsic x, then y, then z rotations by ``angles_deg`` (degrees): ``Rz @ Ry @ Rx``."""
    ax, ay, az = np.radians(np.asarray(angles_deg, dtype=np.float64).ravel())
    cx, sx, cy, sy, cz, sz = np.cos(ax), np.sin(ax), np.cos(ay), np.sin(ay), np.cos(az), np.sin(az)
    Rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    Ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    Rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


def look_at_rotation(forward, up_hint=(0.0, -1.0, 0.0)) -> np.ndarray:
    """Rotation (3, 3) whose columns are an object's x, y, z axes in world, with z along ``forward``."""
    z = np.asarray(forward, dtype=np.float64)
    z = z / np.linalg.norm(z)
    up = np.asarray(up_hint, dtype=np.float64)
    x = np.cross(up, z)
    if np.linalg.norm(x) < 1e-9:
        x = np.cross([1.0, 0.0, 0.0], z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return np.stack([x, y, z], axis=1)


def posed_mesh(name, vertices, triangles, *, rotation=None, translation=None, scale=1.0,
               material: Material | None = None, albedo_texture=None, uv=None) -> SceneMesh:
    """A SceneMesh from object-frame vertices: ``X_world = rotation @ (scale * X_obj) + translation``.

    A negative determinant of ``diag(scale)`` (a mirror) flips the triangles so normals stay outward.
    """
    scale = np.broadcast_to(np.asarray(scale, dtype=np.float64), (3,))
    R = np.eye(3) if rotation is None else np.asarray(rotation, dtype=np.float64)
    t = np.zeros(3) if translation is None else np.asarray(translation, dtype=np.float64).ravel()
    world = (np.asarray(vertices, dtype=np.float64) * scale) @ R.T + t
    triangles = np.asarray(triangles)
    if np.prod(scale) < 0:
        triangles = triangles[:, ::-1]
    return SceneMesh(name=name, vertices=world, triangles=triangles, material=material or Material(),
                     albedo_texture=albedo_texture, uv=uv)
