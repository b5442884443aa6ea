"""Seeded random scenes in the paper's spirit (its Methods: objects scaled to the field of view, randomized depth,
randomized Principled-BSDF roughness and IOR): several disconnected objects that occlude each other, sharp
depth steps, random poses and materials, sized to the rig's field of view and working distance."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from dptpu.fpp.calibration import Rig
from dptpu.sim.rig import working_distance
from dptpu.sim.scene_mesh import Material

from . import primitives
from .scene import Scene, look_at_rotation, posed_mesh
from .scene_file import load_mesh_file

__all__ = ["random_scene", "MESH_SUFFIXES", "RANDOM_SHAPES"]

#: Mesh files drawn from ``meshes_dir``.
MESH_SUFFIXES = (".stl", ".obj", ".ply", ".off", ".gltf", ".glb")
#: Procedural shapes drawn by the generator.
RANDOM_SHAPES = ("sphere", "box", "cylinder", "torus", "superquadric", "blob", "step_block")


def _random_rotation(rng) -> np.ndarray:
    q = rng.normal(size=4)
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def _random_material(rng) -> Material:
    return Material(albedo=float(rng.uniform(0.25, 0.95)), roughness=float(rng.uniform(0.15, 1.0)),
                    specular=float(rng.uniform(0.0, 0.5)), ior=float(rng.uniform(1.3, 1.9)))


def _procedural(rng, shape: str, size: float):
    """A shape whose largest extent is about ``size``."""
    r = size / 2.0
    if shape == "sphere":
        return primitives.sphere(r * rng.uniform(0.6, 1.0), 4)
    if shape == "box":
        return primitives.box(size * rng.uniform(0.4, 1.0, 3))
    if shape == "cylinder":
        return primitives.cylinder(r * rng.uniform(0.3, 0.7), size * rng.uniform(0.5, 1.0), 48)
    if shape == "torus":
        major = r * rng.uniform(0.55, 0.75)
        return primitives.torus(major, major * rng.uniform(0.2, 0.5), 48)
    if shape == "superquadric":
        return primitives.superquadric(r * rng.uniform(0.5, 1.0, 3), rng.uniform(0.2, 1.5, 2), 48)
    if shape == "blob":
        return primitives.blob(r * 0.8, float(rng.uniform(0.1, 0.3)), seed=int(rng.integers(1 << 31)))
    heights = size * rng.uniform(0.1, 0.6, int(rng.integers(2, 5)))
    return primitives.step_block(size, size * rng.uniform(0.5, 1.0), heights)


def _mesh_files(meshes_dir) -> list[Path]:
    folder = Path(meshes_dir)
    if not folder.is_dir():
        raise FileNotFoundError(f"{folder}: no such meshes folder")
    files = sorted(p for p in folder.rglob("*") if p.suffix.lower() in MESH_SUFFIXES)
    if not files:
        raise ValueError(f"{folder}: no mesh files ({', '.join(MESH_SUFFIXES)})")
    return files


def random_scene(rig: Rig, seed: int, *, meshes_dir=None, objects=(3, 6), background_probability: float = 0.7,
                 mesh_fraction: float = 0.7) -> Scene:
    """A seeded random scene placed where the camera and the projector both look.

    Parameters
    ----------
    rig : Rig
    seed : int
        Same seed, same scene (``numpy.random.default_rng(seed)``).
    meshes_dir : path-like, optional
        Folder of user meshes (e.g. Thingi10K): each object is drawn from it with probability ``mesh_fraction``
        (scaled to the object size), otherwise procedural.
    objects : (int, int)
        Range (inclusive) of the number of objects.
    background_probability : float
        Chance of a tilted background plane behind the objects (more occlusion and depth steps).

    Returns
    -------
    Scene
        Objects 0.25-0.6 of the camera's field-of-view height, centres at 0.9-1.1 of the working distance, inside
        the central 70 % of the camera image and inside the projector's image; random orientation and material
        (albedo 0.25-0.95, roughness 0.15-1, specular 0-0.5, IOR 1.3-1.9).
    """
    rng = np.random.default_rng(seed)
    files = _mesh_files(meshes_dir) if meshes_dir is not None else []
    distance = working_distance(rig)
    camera, projector = rig.camera, rig.projector
    width, height = camera.size
    fov_height = height / camera.K[1, 1] * distance
    R_cw = camera.R.T
    meshes = []
    count = int(rng.integers(objects[0], objects[1] + 1))
    for k in range(count):
        size = fov_height * rng.uniform(0.25, 0.6)
        for _ in range(50):
            u = rng.uniform(0.15, 0.85) * width
            v = rng.uniform(0.15, 0.85) * height
            depth = distance * rng.uniform(0.9, 1.1)
            ray = np.linalg.solve(camera.K, np.array([u, v, 1.0]))
            centre = camera.center + R_cw @ (ray * depth)
            p = projector.K @ (projector.R @ centre + projector.T)
            px, py = p[:2] / p[2]
            if 0.1 * projector.size[0] < px < 0.9 * projector.size[0] and \
                    0.1 * projector.size[1] < py < 0.9 * projector.size[1]:
                break
        if files and rng.uniform() < mesh_fraction:
            path = files[int(rng.integers(len(files)))]
            vertices, triangles = load_mesh_file(path)
            low, high = vertices.min(0), vertices.max(0)
            vertices = (vertices - (low + high) / 2.0) * (size / max(float((high - low).max()), 1e-12))
            name = f"object{k}-{path.stem}"
        else:
            shape = RANDOM_SHAPES[int(rng.integers(len(RANDOM_SHAPES)))]
            vertices, triangles = _procedural(rng, shape, size)
            name = f"object{k}-{shape}"
        meshes.append(posed_mesh(name, vertices, triangles, rotation=_random_rotation(rng), translation=centre,
                                 material=_random_material(rng)))
    if rng.uniform() < background_probability:
        depth = distance * rng.uniform(1.12, 1.25)
        tilt = np.radians(rng.uniform(-20.0, 20.0, 2))
        forward = np.array([np.tan(tilt[0]), np.tan(tilt[1]), 1.0])
        vertices, triangles, _ = primitives.plane((4.0 * fov_height * width / height, 4.0 * fov_height), 1)
        # plane faces -z of its frame: its frame z must point away from the camera
        rotation = R_cw @ look_at_rotation(forward)
        meshes.append(posed_mesh("background", vertices, triangles, rotation=rotation,
                                 translation=camera.center + R_cw[:, 2] * depth, material=_random_material(rng)))
    return Scene(meshes=meshes, name=f"random-{seed}", source=f"random(seed={seed}"
                 + (f", meshes={meshes_dir})" if meshes_dir is not None else ")"))
