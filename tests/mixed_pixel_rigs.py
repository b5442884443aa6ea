"""Small analytic captures of rigs unlike the project's own, with mixed pixels at depth edges (test data).

A pinhole camera at the world origin looks along +z at spheres in front of a tilted plane; a pinhole projector
``baseline_mm`` to the side, turned in by ``toe_in_deg``, casts phase-shifted fringes along its x axis. Each camera
pixel is rendered at ``supersample x supersample`` sub-pixel rays and box-averaged down, as a real camera integrates
its pixel area, so the pixels that straddle a depth edge mix foreground and background (and their phase is neither).
Shadows (a sphere between a surface point and the projector) receive ambient light only. Noise is Gaussian, in
camera digital numbers, before 8-bit quantization.

:func:`render` returns the frames and the truth: per pixel the projector coordinate and depth of the centre ray, a
``pure`` mask (every sub-pixel ray hits one object, lit by the projector) and :meth:`MixedPixelScene.distance_mm`,
the distance of any 3-D point to the nearest true surface. The renderer shares no code with ``dptpu.sim`` (an
independent renderer to test against); the rig (``OutsideRig``, :class:`dptpu.sim.outside_rigs.MixedPixelRig`)
lives with the other outside rigs.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from dptpu.fpp.rig_model import Rig
from dptpu.sim.outside_rigs import MIXED_PIXEL_PROJECTOR_SIZE as PROJECTOR_SIZE
from dptpu.sim.outside_rigs import MixedPixelRig as OutsideRig

__all__ = ["PROJECTOR_SIZE", "MixedPixelCapture", "MixedPixelScene", "OutsideRig", "default_scene", "render"]


@dataclass(frozen=True)
class MixedPixelScene:
    """Spheres ``(centre mm, radius mm)`` in front of the plane ``normal . X = offset`` (mm)."""

    spheres: tuple[tuple[tuple[float, float, float], float], ...]
    plane_normal: tuple[float, float, float]
    plane_offset_mm: float

    def hit(self, origin: np.ndarray, direction: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Nearest hit of rays ``origin + t * direction`` (..., 3): ``(t, object)``; object -1 = nothing, 0 = plane,
        1.. = spheres."""
        t_best = np.full(direction.shape[:-1], np.inf)
        which = np.full(direction.shape[:-1], -1)
        n = np.asarray(self.plane_normal, float)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (self.plane_offset_mm - origin @ n) / (direction @ n)
        better = (t > 1e-6) & (t < t_best)
        t_best, which = np.where(better, t, t_best), np.where(better, 0, which)
        for i, (centre, radius) in enumerate(self.spheres, start=1):
            oc = origin - np.asarray(centre, float)
            b = np.sum(oc * direction, axis=-1)
            c = np.sum(oc * oc, axis=-1) - radius**2
            a = np.sum(direction * direction, axis=-1)
            disc = b * b - a * c
            with np.errstate(invalid="ignore"):
                t = (-b - np.sqrt(disc)) / a
            better = (disc > 0) & (t > 1e-6) & (t < t_best)
            t_best, which = np.where(better, t, t_best), np.where(better, i, which)
        return t_best, which

    def normal(self, points: np.ndarray, which: np.ndarray) -> np.ndarray:
        normals = np.broadcast_to(np.asarray(self.plane_normal, float), points.shape).copy()
        for i, (centre, radius) in enumerate(self.spheres, start=1):
            sel = which == i
            normals[sel] = (points[sel] - np.asarray(centre, float)) / radius
        return normals

    def distance_mm(self, points: np.ndarray) -> np.ndarray:
        """Distance (mm) of points (..., 3) to the nearest true surface."""
        n = np.asarray(self.plane_normal, float)
        best = np.abs(points @ n - self.plane_offset_mm)
        for centre, radius in self.spheres:
            best = np.minimum(best, np.abs(np.linalg.norm(points - np.asarray(centre, float), axis=-1) - radius))
        return best


@dataclass(frozen=True, eq=False)
class MixedPixelCapture:
    """Frames and truth of one render (see :func:`render`)."""

    rig: Rig
    scene: MixedPixelScene
    frames: dict[float, np.ndarray]  # frequency -> (N, H, W) uint8
    projector_x: np.ndarray  # (H, W) centre ray, projector pixels, NaN where nothing is hit
    depth_mm: np.ndarray  # (H, W) centre ray z
    pure: np.ndarray  # (H, W) bool: one object, lit, over the whole pixel
    lit: np.ndarray  # (H, W) bool: the centre ray's point is lit by the projector
    extras: dict = field(default_factory=dict)


def default_scene(rig: OutsideRig, *, seed: int = 0) -> MixedPixelScene:
    """Two or three spheres well in front of a plane tilted 20-35 deg, all inside the camera's view."""
    rng = np.random.default_rng(seed)
    d = rig.distance_mm
    tilt = np.deg2rad(rng.uniform(20, 35))
    normal = (np.sin(tilt) * rng.choice([-1, 1]), 0.0, -np.cos(tilt))
    half_w = 0.5 * rig.camera_size[0] / rig.camera_focal_px  # tan of the half field of view
    half_h = 0.5 * rig.camera_size[1] / rig.camera_focal_px
    spheres = []
    for _ in range(int(rng.integers(2, 4))):
        z = d * rng.uniform(0.7, 0.85)
        r = z * half_h * rng.uniform(0.25, 0.4)
        x = z * half_w * rng.uniform(-0.55, 0.55)
        y = z * half_h * rng.uniform(-0.4, 0.4)
        spheres.append(((x, y, z), r))
    return MixedPixelScene(spheres=tuple(spheres), plane_normal=normal, plane_offset_mm=-np.cos(tilt) * d)


def render(rig: OutsideRig, scene: MixedPixelScene, frequencies, *, steps: int = 3, noise_dn: float = 0.0,
           supersample: int = 4, seed: int = 0, amplitude_dn: float = 110.0, offset_dn: float = 120.0,
           ambient_dn: float = 8.0) -> MixedPixelCapture:
    """Render ``steps``-step fringes of each frequency (periods across the projector width); Eq. (1) convention
    ``I_n = A + B cos(phi - 2 pi n / N)``, ``phi = 2 pi f x_p / W_p``."""
    model = rig.rig()
    w, h = rig.camera_size
    k = supersample
    sub = (np.arange(k) + 0.5) / k - 0.5
    u = (np.arange(w)[:, None] + sub[None, :]).ravel()  # (w*k,)
    v = (np.arange(h)[:, None] + sub[None, :]).ravel()
    uu, vv = np.meshgrid(u, v)  # (h*k, w*k)
    K = model.camera.K
    rays = np.stack([(uu - K[0, 2]) / K[0, 0], (vv - K[1, 2]) / K[1, 1], np.ones_like(uu)], axis=-1)
    t, which = scene.hit(np.zeros(3), rays)
    points = rays * t[..., None]
    hit = which >= 0
    points = np.where(hit[..., None], points, 0.0)
    proj = model.projector
    dev = points @ proj.R.T + proj.T
    with np.errstate(divide="ignore", invalid="ignore"):
        x_p = proj.K[0, 0] * dev[..., 0] / dev[..., 2] + proj.K[0, 2]
        y_p = proj.K[1, 1] * dev[..., 1] / dev[..., 2] + proj.K[1, 2]
    centre = -proj.R.T @ proj.T
    to_projector = centre - points
    distance = np.linalg.norm(to_projector, axis=-1)
    light = to_projector / np.maximum(distance, 1e-9)[..., None]
    t_block, _ = scene.hit(points + 1e-3 * light, light)
    shade = np.sum(scene.normal(points, which) * light, axis=-1)
    lit = (hit & (t_block >= distance - 1e-3) & (shade > 0) & (dev[..., 2] > 0)
           & (x_p >= 0) & (x_p <= PROJECTOR_SIZE[0] - 1) & (y_p >= 0) & (y_p <= PROJECTOR_SIZE[1] - 1))
    gain = np.where(lit, shade, 0.0) * hit  # (h*k, w*k)
    rng = np.random.default_rng(seed)
    frames = {}
    for f in frequencies:
        phi = 2 * np.pi * f * np.where(lit, x_p, 0.0) / PROJECTOR_SIZE[0]
        stack = np.empty((steps, h, w), np.uint8)
        for n in range(steps):
            fine = ambient_dn * hit + gain * (offset_dn + amplitude_dn * np.cos(phi - 2 * np.pi * n / steps))
            coarse = fine.reshape(h, k, w, k).mean(axis=(1, 3))
            noisy = coarse + rng.normal(0.0, noise_dn, coarse.shape) if noise_dn else coarse
            stack[n] = np.clip(np.rint(noisy), 0, 255).astype(np.uint8)
        frames[float(f)] = stack
    blocks = which.reshape(h, k, w, k)
    one_object = np.all(blocks == blocks[:, :1, :, :1], axis=(1, 3))
    all_lit = np.all(lit.reshape(h, k, w, k), axis=(1, 3))
    centre_rays = np.stack([(np.arange(w)[None, :] - K[0, 2]) / K[0, 0] + 0 * np.arange(h)[:, None],
                            (np.arange(h)[:, None] - K[1, 2]) / K[1, 1] + 0 * np.arange(w)[None, :],
                            np.ones((h, w))], axis=-1)
    t_c, which_c = scene.hit(np.zeros(3), centre_rays)
    pc = centre_rays * t_c[..., None]
    dev_c = pc @ proj.R.T + proj.T
    with np.errstate(divide="ignore", invalid="ignore"):
        xp_c = np.where(which_c >= 0, proj.K[0, 0] * dev_c[..., 0] / dev_c[..., 2] + proj.K[0, 2], np.nan)
    return MixedPixelCapture(rig=model, scene=scene, frames=frames, projector_x=xp_c,
                             depth_mm=np.where(which_c >= 0, pc[..., 2], np.nan), pure=one_object & all_lit,
                             lit=lit.reshape(h, k, w, k)[:, k // 2, :, k // 2])
