"""The fast renderer's geometry: one camera ray per pixel through the calibrated models, on open3d's
``RaycastingScene``.

Per camera pixel (u, v) (0-based centres):

1. the ray through the camera model with its distortion: the pixel is undistorted (fixed-point inverse of the
   Brown-Conrady model, :func:`dptpu.fpp.distortion.undistort`) into a normalized direction, turned into the
   world by ``R^T`` (the paper's Eq. (10) inverted);
2. the first hit with the scene's triangles (open3d, float32), refined in float64 by intersecting the ray with
   the hit triangle's plane, so points are exact to ~1e-9 of the distance;
3. the projector coordinate of the hit point through the projector model WITH its distortion,
   ``x_p = K_p distort(R_p X + T_p)``;
4. a shadow ray from the hit point to the projector's centre: the point is ``lit`` when nothing blocks it, its
   surface faces the projector (the triangle's face normal and the interpolated shading normal both: the image is
   shaded with the latter, so a point whose shading normal turns away is black however its triangle lies), and
   ``x_p`` falls on the projector's panel.

Everything is vectorized over pixels; the only Python loops are over meshes.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from dptpu.fpp.calibration import Rig
from dptpu.fpp.distortion import distort, normalized_to_pixels
from dptpu.fpp.triangulate import camera_rays

if TYPE_CHECKING:
    import open3d as o3d

__all__ = ["SurfaceSamples", "trace", "project_to_projector"]

#: Offset of shadow-ray origins along the surface normal, as a fraction of the camera distance.
SHADOW_OFFSET_FRACTION = 2e-6


@dataclass(frozen=True, eq=False)
class SurfaceSamples:
    """What the camera sees at each pixel: geometry, projector coordinate, visibility, material.

    Attributes (H, W = camera height, width)
    ----------------------------------------
    points : ndarray (H, W, 3) float64
        Hit points in world coordinates, rig units; NaN where ``~hit``.
    normals : ndarray (H, W, 3) float64
        Unit shading normals (interpolated vertex normals), turned towards the camera; NaN where ``~hit``.
    depth : ndarray (H, W) float64
        Depth along the camera's z axis, rig units; NaN where ``~hit``.
    projector_xy : ndarray (H, W, 2) float64
        Projector pixel coordinates (x = column, y = row, 0-based centres) through the projector model with its
        distortion; NaN where ``~hit``.
    lit : ndarray (H, W) bool
        The projector lights the point: hit, on the projector's panel, facing the projector, no occluder.
    hit : ndarray (H, W) bool
        The camera ray hits a mesh.
    albedo, roughness, specular, ior : ndarray (H, W) float32
        Material at the hit (albedo includes the texture lookup); 0 where ``~hit``.
    mesh_index : ndarray (H, W) int32
        Index of the hit mesh in the traced list, -1 where ``~hit``.
    rig : Rig
        The rig traced (the geometry-stage effects already applied).
    meshes : tuple of SceneMesh
        The meshes traced (the ``motion`` effect re-traces them moved).
    """

    points: np.ndarray
    normals: np.ndarray
    depth: np.ndarray
    projector_xy: np.ndarray
    lit: np.ndarray
    hit: np.ndarray
    albedo: np.ndarray
    roughness: np.ndarray
    specular: np.ndarray
    ior: np.ndarray
    mesh_index: np.ndarray
    rig: Rig = field(repr=False)
    meshes: tuple = field(repr=False, default=())

    @property
    def shape(self) -> tuple[int, int]:
        return self.hit.shape


def project_to_projector(rig: Rig, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Projector pixel coordinates (..., 2) of world points (..., 3) with the projector's distortion, and the
    depth (...,) in the projector frame (positive in front)."""
    projector = rig.projector
    local = points @ projector.R.T + projector.T  # (..., 3)
    z = local[..., 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        xy = local[..., :2] / z[..., None]
    return normalized_to_pixels(distort(xy, projector.dist), projector.K), z


_RAY_CACHE: dict = {}
_RAY_CACHE_SIZE = 4


def _camera_rays(camera) -> np.ndarray:
    """Unit world ray directions (H*W, 3) of the camera's pixel centres, cached per camera model (a dataset renders
    many scenes with one rig; undistorting the pixel grid is a third of a trace)."""
    key = (camera.K.tobytes(), camera.dist.tobytes(), camera.R.tobytes(), camera.T.tobytes(), tuple(camera.size))
    rays = _RAY_CACHE.get(key)
    if rays is None:
        rays = camera_rays(camera).reshape(-1, 3)
        rays.setflags(write=False)
        if len(_RAY_CACHE) >= _RAY_CACHE_SIZE:
            _RAY_CACHE.pop(next(iter(_RAY_CACHE)))
        _RAY_CACHE[key] = rays
    return rays


def _vertex_normals(vertices: np.ndarray, triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Area-weighted vertex normals (V, 3) and face normals (T, 3), unit length."""
    v0, v1, v2 = (vertices[triangles[:, i]] for i in range(3))
    face = np.cross(v1 - v0, v2 - v0)  # (T, 3), length = 2 * area
    normals = np.zeros_like(vertices)
    for i in range(3):
        np.add.at(normals, triangles[:, i], face)
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-300)
    face /= np.maximum(np.linalg.norm(face, axis=1, keepdims=True), 1e-300)
    return normals, face


def _o3d_tensor(array: np.ndarray) -> o3d.core.Tensor:
    """An open3d tensor holding a copy of ``array`` (the array's dtype, on the CPU)."""
    import open3d as o3d  # heavy: loaded on first use

    # open3d's generated stub makes ``dtype`` and ``device`` required; at runtime both are optional (the array's
    # dtype, CPU:0), so the one-argument call matches no overload of the stub
    return o3d.core.Tensor(array)  # type: ignore[call-overload]


def _bilinear(texture: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Texture (Ht, Wt) sampled at uv (M, 2) in [0, 1] (texel centres at (i + 0.5) / Wt), clamped at the edge."""
    height, width = texture.shape
    x = np.clip(uv[:, 0] * width - 0.5, 0.0, width - 1.0)
    y = np.clip(uv[:, 1] * height - 0.5, 0.0, height - 1.0)
    x0, y0 = np.floor(x).astype(np.int64), np.floor(y).astype(np.int64)
    x1, y1 = np.minimum(x0 + 1, width - 1), np.minimum(y0 + 1, height - 1)
    fx, fy = x - x0, y - y0
    top = texture[y0, x0] * (1 - fx) + texture[y0, x1] * fx
    bottom = texture[y1, x0] * (1 - fx) + texture[y1, x1] * fx
    return top * (1 - fy) + bottom * fy


def trace(rig: Rig, meshes) -> SurfaceSamples:
    """Trace every camera pixel of ``rig`` into ``meshes``.

    Parameters
    ----------
    rig : Rig
        Camera and projector models (their distortion is rendered).
    meshes : list of SceneMesh or Scene
        Triangles in the rig's world frame and units.

    Returns
    -------
    SurfaceSamples
    """
    import open3d as o3d  # heavy: loaded on first use

    if hasattr(meshes, "meshes"):
        meshes = meshes.meshes
    meshes = tuple(meshes)
    if not meshes:
        raise ValueError("trace needs at least one mesh")
    camera = rig.camera
    width, height = camera.size
    origin = camera.center  # (3,) open3d works in float32: trace relative to the camera centre
    directions = _camera_rays(camera)  # (P, 3) unit, world (read-only, cached)
    scene = o3d.t.geometry.RaycastingScene()
    geometry_to_mesh = {}
    prepared = []
    for index, mesh in enumerate(meshes):
        vertices = mesh.vertices - origin
        gid = scene.add_triangles(_o3d_tensor(vertices.astype(np.float32)),
                                  _o3d_tensor(mesh.triangles.astype(np.uint32)))
        geometry_to_mesh[int(gid)] = index
        prepared.append((vertices, *_vertex_normals(mesh.vertices, mesh.triangles)))
    lookup = np.full(max(geometry_to_mesh) + 2, -1, dtype=np.int32)
    for gid, index in geometry_to_mesh.items():
        lookup[gid] = index

    rays = np.hstack([np.zeros_like(directions), directions]).astype(np.float32)
    answer = scene.cast_rays(_o3d_tensor(rays))
    t_hit = answer["t_hit"].numpy()
    gids = answer["geometry_ids"].numpy().astype(np.int64)
    prims = answer["primitive_ids"].numpy().astype(np.int64)
    hit = np.isfinite(t_hit)
    gids = np.where(hit, gids, len(lookup) - 1)
    mesh_index = lookup[np.minimum(gids, len(lookup) - 1)]
    hit &= mesh_index >= 0

    pixels = height * width
    t = np.full(pixels, np.nan)
    normals = np.full((pixels, 3), np.nan)
    face_normals = np.full((pixels, 3), np.nan)
    albedo = np.zeros(pixels, np.float32)
    roughness = np.zeros(pixels, np.float32)
    specular = np.zeros(pixels, np.float32)
    ior = np.zeros(pixels, np.float32)
    for index, (mesh, (vertices, vertex_normals, face)) in enumerate(zip(meshes, prepared)):
        sel = np.flatnonzero(hit & (mesh_index == index))
        if sel.size == 0:
            continue
        tri = mesh.triangles[prims[sel]]  # (M, 3)
        a, b, c = vertices[tri[:, 0]], vertices[tri[:, 1]], vertices[tri[:, 2]]
        d = directions[sel]
        n_face = face[prims[sel]]
        # float64 ray-plane intersection and barycentrics (Moller-Trumbore)
        e1, e2 = b - a, c - a
        p = np.cross(d, e2)
        det = np.einsum("ij,ij->i", e1, p)
        s = -a
        bu = np.einsum("ij,ij->i", s, p) / det
        q = np.cross(s, e1)
        bv = np.einsum("ij,ij->i", d, q) / det
        t[sel] = np.einsum("ij,ij->i", e2, q) / det
        w0 = 1.0 - bu - bv
        n = (w0[:, None] * vertex_normals[tri[:, 0]] + bu[:, None] * vertex_normals[tri[:, 1]]
             + bv[:, None] * vertex_normals[tri[:, 2]])
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
        normals[sel] = n
        face_normals[sel] = n_face
        material = mesh.material
        value = np.full(sel.size, material.albedo, np.float32)
        if mesh.albedo_texture is not None:
            uv = w0[:, None] * mesh.uv[tri[:, 0]] + bu[:, None] * mesh.uv[tri[:, 1]] + bv[:, None] * mesh.uv[tri[:, 2]]
            value = value * _bilinear(mesh.albedo_texture, uv).astype(np.float32)
        albedo[sel], roughness[sel] = value, material.roughness
        specular[sel], ior[sel] = material.specular, material.ior
    hit &= np.isfinite(t) & (t > 0)
    points = origin + directions * t[:, None]  # (P, 3) float64, NaN where no hit
    # normals towards the camera (both faces of open meshes render)
    facing = np.einsum("ij,ij->i", face_normals, directions) > 0
    face_normals[facing] *= -1
    flip = np.einsum("ij,ij->i", normals, face_normals) < 0
    normals[flip] *= -1

    projector_xy, projector_z = project_to_projector(rig, points)
    pw, ph = rig.projector.size
    on_panel = (hit & (projector_z > 0) & (projector_xy[:, 0] >= -0.5) & (projector_xy[:, 0] <= pw - 0.5)
                & (projector_xy[:, 1] >= -0.5) & (projector_xy[:, 1] <= ph - 0.5))
    to_projector = rig.projector.center - points
    distance = np.linalg.norm(to_projector, axis=1)
    to_projector /= distance[:, None]
    # both normals: the face's (the mesh) and the shading normal the image is lit by (image_formation's cos_i); a
    # point whose shading normal turns away from the projector gets no light (an attached shadow) and is not lit
    faces_projector = ((np.einsum("ij,ij->i", face_normals, to_projector) > 0)
                       & (np.einsum("ij,ij->i", normals, to_projector) > 0))
    candidates = np.flatnonzero(on_panel & faces_projector)
    lit = np.zeros(pixels, bool)
    if candidates.size:
        offset = SHADOW_OFFSET_FRACTION * t[candidates]
        starts = points[candidates] - origin + face_normals[candidates] * offset[:, None]
        shadow = np.hstack([starts, to_projector[candidates]]).astype(np.float32)
        blocked_t = scene.cast_rays(_o3d_tensor(shadow))["t_hit"].numpy()
        lit[candidates] = ~(blocked_t < distance[candidates] - 2.0 * offset)

    depth = (points - origin) @ camera.R[2]  # z in the camera frame (R[2] = camera z axis in world)
    shape = (height, width)
    nan3 = ~hit
    points[nan3] = np.nan
    normals[nan3] = np.nan
    projector_xy[nan3] = np.nan
    depth[nan3] = np.nan
    return SurfaceSamples(points=points.reshape(*shape, 3), normals=normals.reshape(*shape, 3),
                          depth=depth.reshape(shape), projector_xy=projector_xy.reshape(*shape, 2),
                          lit=lit.reshape(shape), hit=hit.reshape(shape), albedo=albedo.reshape(shape),
                          roughness=roughness.reshape(shape), specular=specular.reshape(shape),
                          ior=ior.reshape(shape),
                          mesh_index=np.where(hit, mesh_index, -1).astype(np.int32).reshape(shape),
                          rig=rig, meshes=meshes)
