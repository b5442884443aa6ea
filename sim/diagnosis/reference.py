"""The reference object of a diagnosis, as an analytic surface: what the twin should have seen at each pixel.

A reference is a sphere of known diameter (``sphere:DIAMETER_MM``), a plane (``plane``) or a scene file
(``scene:FILE``, traced as placed). For the analytic shapes the camera ray of every pixel (with the camera's
distortion) is intersected exactly with the surface, and the hit point goes through the projector model (the
paper's Eq. (10) with the lens model of Table 1): the projector coordinate, the normal and the visibility of
each pixel, with no mesh facets.

Convention: pose parameters are in the rig's world frame and units; a plane is ``n . X = d`` with ``n`` from
two tilt parameters about the camera's optical axis, ``n_c = (a, b, -1) / |(a, b, -1)|`` in the camera frame
(facing the camera).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from dptpu.fpp.calibration import Rig
from dptpu.fpp.triangulate import camera_rays
from dptpu.sim.raycast import SurfaceSamples, project_to_projector, trace
from dptpu.sim.scene_mesh import SceneMesh
from dptpu.sim.scenes import Scene, load_scene_file

__all__ = ["Reference", "parse_reference", "load_scene_reference", "SurfaceHits", "surface_hits", "reference_hits",
           "translated_pose", "posed_meshes"]


@dataclass(frozen=True)
class Reference:
    """A reference object: ``kind`` in {"sphere", "plane", "scene", "self"}; ``diameter`` (rig units) for a
    sphere; ``path`` for a scene file and, once loaded for a rig (:func:`load_scene_reference`), ``scene`` (its
    :class:`~dptpu.sim.scenes.scene.Scene` at the file's pose)."""

    kind: str
    diameter: float | None = None
    path: str | None = None
    scene: Scene | None = field(default=None, compare=False, repr=False)

    @property
    def pose_size(self) -> int:
        """Number of pose parameters fitted by the registration."""
        return {"sphere": 3, "plane": 3}.get(self.kind, 0)

    @property
    def sphere_diameter(self) -> float:
        """The diameter of a sphere reference, rig units."""
        if self.diameter is None:
            raise ValueError(f"reference {self.label!r} has no diameter (a sphere:DIAMETER_MM reference has)")
        return self.diameter

    @property
    def label(self) -> str:
        if self.kind == "sphere":
            return f"sphere:{self.diameter:g}"
        return self.kind if self.path is None else f"scene:{self.path}"


def parse_reference(text) -> Reference:
    """``sphere:DIAMETER_MM``, ``plane``, ``scene:FILE`` or ``self`` (self-reference) -> :class:`Reference`."""
    text = "self" if text is None else str(text).strip()
    if text in ("plane", "self"):
        return Reference(text)
    kind, _, value = text.partition(":")
    if kind == "sphere":
        try:
            diameter = float(value)
        except ValueError:
            diameter = float("nan")
        if not np.isfinite(diameter) or diameter <= 0:
            raise ValueError(f"--reference sphere:DIAMETER_MM needs a diameter > 0 in mm (e.g. sphere:50.8082); "
                             f"got {text!r}")
        return Reference("sphere", diameter=diameter)
    if kind == "scene" and value:
        return Reference("scene", path=value)
    raise ValueError(f"--reference must be sphere:DIAMETER_MM, plane or scene:FILE; got {text!r}")


def load_scene_reference(reference: Reference, rig: Rig) -> Reference:
    """``reference`` with its scene file loaded for ``rig`` (``scene:FILE``; other kinds unchanged).

    Raises
    ------
    FileNotFoundError, ValueError
        No such file, or an invalid scene file (the message names the file and the key).
    """
    if reference.kind != "scene" or reference.scene is not None:
        return reference

    return replace(reference, scene=load_scene_file(reference.path, rig))


@dataclass(frozen=True)
class SurfaceHits:
    """Per pixel (H, W): ``points`` (H, W, 3), ``normals`` (H, W, 3) (unit, towards the camera),
    ``projector_xy`` (H, W, 2), ``hit`` and ``lit`` (bool), ``projector_depth`` (H, W); for a traced scene
    also its ``samples`` (:class:`~dptpu.sim.raycast.SurfaceSamples`: the material at each pixel)."""

    points: np.ndarray
    normals: np.ndarray
    projector_xy: np.ndarray
    hit: np.ndarray
    lit: np.ndarray
    projector_depth: np.ndarray
    samples: SurfaceSamples | None = None


def posed_meshes(reference: Reference, pose) -> tuple:
    """The scene's meshes moved by the rigid transform ``pose`` (4, 4): ``X -> R X + t`` (world frame)."""
    if reference.scene is None:
        raise ValueError(f"reference {reference.label!r}: the scene file is not loaded (load_scene_reference)")
    pose = np.asarray(pose, dtype=np.float64)
    R, t = pose[:3, :3], pose[:3, 3]
    return tuple(SceneMesh(name=m.name, vertices=m.vertices @ R.T + t, triangles=m.triangles, material=m.material,
                           albedo_texture=m.albedo_texture, uv=m.uv) for m in reference.scene.meshes)


def reference_hits(rig: Rig, reference: Reference, pose) -> SurfaceHits:
    """What each pixel sees of the reference at ``pose``: :func:`surface_hits` for the analytic shapes, the
    twin's ray cast (:func:`dptpu.sim.raycast.trace`) of the scene's meshes moved by ``pose`` (4, 4) for a
    scene."""
    if reference.kind != "scene":
        return surface_hits(rig, reference.kind, pose, diameter=reference.diameter)

    samples = trace(rig, posed_meshes(reference, pose))
    depth = (samples.points @ rig.projector.R.T + rig.projector.T)[..., 2]
    return SurfaceHits(points=samples.points, normals=samples.normals, projector_xy=samples.projector_xy,
                       hit=samples.hit, lit=samples.lit, projector_depth=depth, samples=samples)


def translated_pose(rig: Rig, reference: Reference, pose, translation) -> np.ndarray:
    """``pose`` of the reference moved by ``translation`` (3,) (world, rig units)."""
    pose = np.array(pose, dtype=np.float64, copy=True)
    translation = np.asarray(translation, dtype=np.float64)
    if reference.kind == "sphere":
        return pose + translation
    if reference.kind == "plane":
        normal = plane_normal(rig, pose[:2])
        pose[2] += float(normal @ translation) / float(normal @ rig.camera.R.T[:, 2])
        return pose
    if reference.kind == "scene":
        pose[:3, 3] += translation
        return pose
    raise ValueError(f"no pose to translate for reference {reference.label!r}")


def plane_normal(rig: Rig, tilt) -> np.ndarray:
    """World unit normal (3,) of a plane from its two tilts ``(a, b)`` (module Convention)."""
    n_cam = np.array([tilt[0], tilt[1], -1.0])
    return rig.camera.R.T @ (n_cam / np.linalg.norm(n_cam))


def surface_hits(rig: Rig, kind: str, pose, *, diameter: float | None = None, rays=None,
                 extend: bool = False) -> SurfaceHits:
    """Exact hits of every camera ray with an analytic sphere or plane.

    Parameters
    ----------
    rig : Rig
    kind : {"sphere", "plane"}
    pose : array (3,)
        Sphere: centre (world, rig units). Plane: ``(a, b, depth)``: tilts and the depth of the plane on the
        camera's optical axis.
    diameter : float
        Sphere diameter, rig units.
    rays : ndarray (H, W, 3), optional
        Unit world rays (default :func:`dptpu.fpp.triangulate.camera_rays` of the rig's camera).
    extend : bool
        Sphere: a ray that misses takes the point closest to the sphere (a continuous extension for fitting).
    """
    rays = camera_rays(rig.camera) if rays is None else rays
    origin = rig.camera.center
    pose = np.asarray(pose, dtype=np.float64)
    if kind == "sphere":
        if diameter is None:
            raise ValueError("an analytic sphere needs its diameter")
        radius = diameter / 2.0
        oc = origin - pose
        b = rays @ oc
        disc = b * b - (oc @ oc - radius * radius)
        t = -b - np.sqrt(np.maximum(disc, 0.0))
        hit = disc > 0
        points = origin + rays * t[..., None]
        normals = (points - pose) / radius
        if extend:
            hit = np.ones_like(hit)
    elif kind == "plane":
        normal = plane_normal(rig, pose[:2])
        axis = rig.camera.R.T[:, 2]
        point = origin + axis * pose[2]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = ((point - origin) @ normal) / (rays @ normal)
        hit = np.isfinite(t) & (t > 0)
        points = origin + rays * t[..., None]
        normals = np.broadcast_to(normal, points.shape).copy()
    else:
        raise ValueError(f"an analytic reference is 'sphere' or 'plane'; got {kind!r}")
    normals = np.where((normals * rays).sum(-1, keepdims=True) > 0, -normals, normals)
    xy, depth = project_to_projector(rig, points)
    width, height = rig.projector.size
    to_projector = rig.projector.center - points
    facing = (normals * to_projector).sum(-1) > 0
    on_panel = (xy[..., 0] >= -0.5) & (xy[..., 0] <= width - 0.5) & (xy[..., 1] >= -0.5) & (xy[..., 1] <= height - 0.5)
    lit = hit & facing & on_panel & (depth > 0)
    if kind == "sphere" and not extend:
        # the projector sees the first hit along its own ray: points behind the sphere's front are shadowed
        lit &= _sphere_front_for_projector(rig, pose, radius, points)
    return SurfaceHits(points=points, normals=normals, projector_xy=xy, hit=hit, lit=lit, projector_depth=depth)


def _sphere_front_for_projector(rig: Rig, center, radius, points) -> np.ndarray:
    """True where ``points`` lie on the projector-facing half of the sphere (no self-shadow)."""
    return ((points - center) * (rig.projector.center - points)).sum(-1) >= -1e-9 * radius
