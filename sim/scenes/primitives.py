"""Procedural triangle meshes for scenes, centred on their own origin, in the rig's units.

Every builder returns ``(vertices (V, 3) float64, triangles (T, 3) int32)`` with triangles counter-clockwise
seen from outside (outward normals ``(v1 - v0) x (v2 - v0)``), the convention of :mod:`dptpu.sim.scene_mesh`.
Closed meshes are checked by their signed volume and flipped when needed.

Shapes: ``sphere`` (icosphere, vertices on the exact sphere), ``box``, ``cylinder``, ``torus``,
``superquadric``, ``blob`` (a sphere with smooth seeded radial bumps), ``step_block`` (a block whose top is a
staircase: sharp depth steps), ``plane`` (a grid in z = 0 facing -z, i.e. towards a camera looking along +z).
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np

__all__ = ["SHAPES", "sphere", "box", "cylinder", "torus", "superquadric", "blob", "step_block", "plane",
           "grid_surface", "orient_outward"]


def orient_outward(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Triangles (T, 3) flipped if the closed mesh's signed volume is negative (inward normals)."""
    v0, v1, v2 = (vertices[triangles[:, i]] for i in range(3))
    volume = np.einsum("ij,ij->i", v0, np.cross(v1, v2)).sum() / 6.0
    return triangles[:, ::-1].copy() if volume < 0 else triangles


def icosphere(subdivisions: int) -> tuple[np.ndarray, np.ndarray]:
    """Unit icosphere: 20 * 4**subdivisions triangles, vertices on the unit sphere."""
    t = (1.0 + 5.0 ** 0.5) / 2.0
    vertices = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t], [0, -1, -t],
                         [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]], dtype=np.float64)
    triangles = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
                          [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
                          [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]], dtype=np.int64)
    vertices /= np.linalg.norm(vertices, axis=1, keepdims=True)
    for _ in range(int(subdivisions)):
        edges = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]])  # (3T, 2)
        edges_sorted = np.sort(edges, axis=1)
        unique, inverse = np.unique(edges_sorted, axis=0, return_inverse=True)
        midpoints = vertices[unique[:, 0]] + vertices[unique[:, 1]]
        midpoints /= np.linalg.norm(midpoints, axis=1, keepdims=True)
        mid_index = len(vertices) + inverse.reshape(3, -1)  # (3, T): edges 01, 12, 20
        vertices = np.vstack([vertices, midpoints])
        a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]
        ab, bc, ca = mid_index
        triangles = np.concatenate([np.stack([a, ab, ca], 1), np.stack([b, bc, ab], 1), np.stack([c, ca, bc], 1),
                                    np.stack([ab, bc, ca], 1)])
    return vertices, orient_outward(vertices, triangles).astype(np.int32)


def sphere(radius: float, subdivisions: int = 5):
    """Sphere of ``radius``: an icosphere with vertices on the exact sphere.

    The flat facets lie inside the sphere by at most (measured, r = 25.4041 mm): 28.9 um at 4 subdivisions
    (5120 triangles), 7.2 um at 5, 1.81 um at 6, 0.45 um at 7 (327680 triangles); it scales with r.
    """
    vertices, triangles = icosphere(subdivisions)
    return vertices * radius, triangles


def grid_surface(points: np.ndarray, *, wrap_u: bool = False, wrap_v: bool = False):
    """Triangles of a (Nu, Nv, 3) grid of points; wrap joins the last row/column to the first."""
    nu, nv = points.shape[:2]
    index = np.arange(nu * nv).reshape(nu, nv)
    if wrap_u:
        index = np.vstack([index, index[:1]])
    if wrap_v:
        index = np.hstack([index, index[:, :1]])
    a, b = index[:-1, :-1].ravel(), index[1:, :-1].ravel()
    c, d = index[1:, 1:].ravel(), index[:-1, 1:].ravel()
    triangles = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return points.reshape(-1, 3).astype(np.float64), triangles.astype(np.int32)


def _remove_degenerate(vertices, triangles):
    v0, v1, v2 = (vertices[triangles[:, i]] for i in range(3))
    area = np.linalg.norm(np.cross(v1 - v0, v2 - v0), axis=1)
    return triangles[area > 1e-12 * max(1.0, np.abs(vertices).max() ** 2)]


def box(size):
    """Axis-aligned box of edge lengths ``size = (sx, sy, sz)`` centred on the origin (12 triangles)."""
    sx, sy, sz = (float(v) / 2.0 for v in size)
    corners = np.array([[x, y, z] for x in (-sx, sx) for y in (-sy, sy) for z in (-sz, sz)])
    # faces as quads of corner indices (index = 4*ix + 2*iy + iz)
    quads = np.array([[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]])
    triangles = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    return corners, orient_outward(corners, triangles).astype(np.int32)


def _closed_revolution(profile_r, profile_z, resolution):
    """Surface of revolution about z of a profile from the axis back to the axis (closed)."""
    angles = np.linspace(0.0, 2.0 * np.pi, resolution, endpoint=False)
    points = np.stack([profile_r[:, None] * np.cos(angles)[None], profile_r[:, None] * np.sin(angles)[None],
                       np.broadcast_to(profile_z[:, None], (len(profile_r), resolution))], axis=-1)
    vertices, triangles = grid_surface(points, wrap_v=True)
    triangles = _remove_degenerate(vertices, triangles)
    return vertices, orient_outward(vertices, triangles)


def cylinder(radius: float, height: float, resolution: int = 64):
    """Closed cylinder about z of ``radius`` and ``height``, centred on the origin."""
    h = height / 2.0
    profile_r = np.array([0.0, radius, radius, 0.0])
    profile_z = np.array([-h, -h, h, h])
    return _closed_revolution(profile_r, profile_z, resolution)


def torus(major_radius: float, minor_radius: float, resolution: int = 64):
    """Torus about z: tube of ``minor_radius`` around a circle of ``major_radius``."""
    if minor_radius >= major_radius:
        raise ValueError(f"torus minor_radius must be < major_radius; got {minor_radius} >= {major_radius}")
    u = np.linspace(0.0, 2.0 * np.pi, resolution, endpoint=False)
    v = np.linspace(0.0, 2.0 * np.pi, max(resolution // 2, 8), endpoint=False)
    uu, vv = np.meshgrid(u, v, indexing="ij")
    ring = major_radius + minor_radius * np.cos(vv)
    points = np.stack([ring * np.cos(uu), ring * np.sin(uu), minor_radius * np.sin(vv)], axis=-1)
    vertices, triangles = grid_surface(points, wrap_u=True, wrap_v=True)
    return vertices, orient_outward(vertices, triangles)


def _signed_power(x, p):
    return np.sign(x) * np.abs(x) ** p


def superquadric(radii, exponents, resolution: int = 64):
    """Superellipsoid ``|x/a|^(2/e2) + |y/b|^(2/e2))^(e2/e1) + |z/c|^(2/e1) = 1`` (Barr), ``radii = (a, b, c)``,
    ``exponents = (e1, e2)``: 1 is an ellipsoid, towards 0 a box, 2 an octahedron."""
    a, b, c = (float(v) for v in radii)
    e1, e2 = (float(v) for v in exponents)
    eta = np.linspace(-np.pi / 2, np.pi / 2, resolution // 2 + 1)
    omega = np.linspace(-np.pi, np.pi, resolution, endpoint=False)
    ee, ww = np.meshgrid(eta, omega, indexing="ij")
    ce, se = _signed_power(np.cos(ee), e1), _signed_power(np.sin(ee), e1)
    points = np.stack([a * ce * _signed_power(np.cos(ww), e2), b * ce * _signed_power(np.sin(ww), e2), c * se], -1)
    vertices, triangles = grid_surface(points, wrap_v=True)
    vertices, triangles = _merge_close(vertices, triangles)
    triangles = _remove_degenerate(vertices, triangles)
    return vertices, orient_outward(vertices, triangles)


def _merge_close(vertices, triangles, decimals: int = 9):
    rounded = np.round(vertices, decimals)
    unique, index, inverse = np.unique(rounded, axis=0, return_index=True, return_inverse=True)
    return vertices[index], inverse.ravel()[triangles].astype(np.int32)


def blob(radius: float, amplitude: float = 0.2, *, seed: int = 0, subdivisions: int = 4, lobes: int = 6):
    """A sphere of ``radius`` with smooth radial bumps: ``r(d) = radius (1 + amplitude * s(d))``, ``s`` a seeded sum
    of ``lobes`` Gaussian bumps on the unit sphere, scaled to [-1, 1]."""
    if not 0 <= amplitude < 1:
        raise ValueError(f"blob amplitude must be in [0, 1); got {amplitude}")
    directions, triangles = icosphere(subdivisions)
    rng = np.random.default_rng(seed)
    centres = rng.normal(size=(lobes, 3))
    centres /= np.linalg.norm(centres, axis=1, keepdims=True)
    weights = rng.uniform(-1.0, 1.0, lobes)
    widths = rng.uniform(0.3, 0.8, lobes)
    field = (weights[None] * np.exp(-(1.0 - directions @ centres.T) / widths[None] ** 2)).sum(axis=1)
    field /= max(np.abs(field).max(), 1e-12)
    vertices = directions * (radius * (1.0 + amplitude * field))[:, None]
    return vertices, orient_outward(vertices, triangles)


def step_block(width: float, depth: float, step_heights):
    """A block of ``width`` (x) by ``depth`` (y) whose height (z, towards -z = towards the camera) changes in
    sharp steps along x: ``len(step_heights)`` equal strips of the given heights. Centred on the origin in x, y;
    its base is at z = 0 and the steps rise to z = -height (the block faces a camera looking along +z)."""
    heights = np.asarray(step_heights, dtype=np.float64).ravel()
    if heights.size < 1 or np.any(heights <= 0):
        raise ValueError(f"step_block step_heights must be positive; got {heights.tolist()}")
    edges = np.linspace(-width / 2.0, width / 2.0, heights.size + 1)
    vertices_list, triangles_list, offset = [], [], 0
    for k, height in enumerate(heights):
        v, t = box((edges[k + 1] - edges[k], depth, height))
        v = v + np.array([(edges[k] + edges[k + 1]) / 2.0, 0.0, -height / 2.0])
        vertices_list.append(v)
        triangles_list.append(t + offset)
        offset += len(v)
    return np.vstack(vertices_list), np.vstack(triangles_list).astype(np.int32)


def plane(size, subdivisions: int = 1):
    """Rectangle ``size = (sx, sy)`` in z = 0 centred on the origin, normal -z (facing a camera looking along +z);
    returns ``(vertices, triangles, uv)`` with uv (V, 2) in [0, 1] (u along +x, v along +y)."""
    sx, sy = (float(v) for v in size)
    n = int(subdivisions) + 1
    u, v = np.meshgrid(np.linspace(0.0, 1.0, n), np.linspace(0.0, 1.0, n), indexing="ij")
    points = np.stack([(u - 0.5) * sx, (v - 0.5) * sy, np.zeros_like(u)], axis=-1)
    vertices, triangles = grid_surface(points)
    # grid order (a, b, c) runs +x then +y: normal +z; flip to face -z
    triangles = triangles[:, ::-1].copy()
    return vertices, triangles, np.stack([u.ravel(), v.ravel()], axis=-1)


#: Shape name -> builder, for scene files.
SHAPES: dict[str, Callable[..., tuple[np.ndarray, ...]]] = {
    "sphere": sphere, "box": box, "cylinder": cylinder, "torus": torus, "superquadric": superquadric, "blob": blob,
    "step_block": step_block, "plane": plane}
