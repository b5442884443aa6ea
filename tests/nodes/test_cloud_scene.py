"""The analytic scene of the node tests: a tilted plane in front of the synthetic rig (tests/fpp/rig_fixtures.py).

Helpers here are imported by the phase, unwrap and cloud tests; the tests in this module check the scene
itself against the textbook per-pixel triangulation (``triangulate_reference``), so the node tests rest on
geometry that is known to be right.

Scene: camera 160 x 120 (the rig's intrinsics scaled), projector 912 x 1140 with vertical fringes, a plane
``n . X = d`` of normal ``(0.12, -0.08, -1)`` through ``(0, 0, 850) mm`` in the camera frame. Every camera
pixel sees the plane; its projector column ``x_p`` follows from projecting the ray-plane point into the
projector with its lens distortion. Frames are ``dptpu.fpp.patterns.fringe_patterns`` sampled at ``x_p``
(``tests/conftest.py::render_phase_frames``: 8 + 0.9 * albedo * level DN, 0.5 DN noise, uint8).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dptpu.fpp.calibration import DeviceModel, Rig
from dptpu.fpp.distortion import distort, normalized_to_pixels
from dptpu.fpp.triangulate import camera_rays, triangulate_reference
from tests.conftest import SYNTHETIC_PROJECTOR_SIZE, SyntheticScene, render_phase_frames
from tests.fpp.rig_fixtures import rotation, synthetic_rig

CAMERA_SIZE = (160, 120)
EXTENT_PX = SYNTHETIC_PROJECTOR_SIZE[0]
PLANE_NORMAL = np.array([0.12, -0.08, -1.0]) / np.linalg.norm([0.12, -0.08, -1.0])
PLANE_POINT_MM = np.array([0.0, 0.0, 850.0])


@dataclass(frozen=True)
class PlaneScene:
    """What every camera pixel sees, all (H, W) or (H, W, 3), camera frame, millimetres."""

    rig: Rig
    points_mm: np.ndarray       # (H, W, 3) ray-plane intersections in the camera frame
    projector_x: np.ndarray     # (H, W) float64 projector column (distorted, as the projector shows it)
    lit: np.ndarray             # (H, W) bool: the column lies on the projector

    def absolute_phase(self, frequency: float) -> np.ndarray:
        """``phi = 2*pi*f*x_p/W`` (H, W) float64, the convention of docs/architecture.md."""
        return 2.0 * np.pi * frequency * self.projector_x / EXTENT_PX

    def wrapped_phase(self, frequency: float) -> np.ndarray:
        return np.mod(self.absolute_phase(frequency), 2.0 * np.pi)

    def frames(self, frequency: float, *, steps: int = 4, seed: int = 0, noise_dn: float = 0.5,
               shadow=None) -> np.ndarray:
        """(steps, H, W) uint8 camera frames of the fringe sequence of ``frequency``.

        ``shadow`` (H, W) bool: pixels the projector does not reach (albedo 0.01: modulation ~1 DN).
        """
        lit = self.lit if shadow is None else self.lit & ~shadow
        scene = SyntheticScene(projector_x=np.where(lit, self.projector_x, 0.0),
                               albedo=np.where(lit, 0.8, 0.01), lit=lit)
        return render_phase_frames(scene, frequency=frequency, steps=steps, noise_dn=noise_dn,
                                   rng=np.random.default_rng(seed)).images


def posed(rig: Rig, R_w: np.ndarray, T_w) -> Rig:
    """The same rig in another world frame, ``X_old = R_w X_new + T_w`` (the camera frame is unchanged)."""
    def move(device: DeviceModel) -> DeviceModel:
        return DeviceModel(K=device.K, dist=device.dist, R=device.R @ R_w, T=device.R @ np.asarray(T_w) + device.T,
                           size=device.size)
    return Rig(camera=move(rig.camera), projector=move(rig.projector), units=rig.units)


def plane_scene(*, world_pose: bool = False) -> PlaneScene:
    """The tilted plane seen by the 160 x 120 synthetic rig; ``world_pose`` puts the world frame elsewhere."""
    rig = synthetic_rig(camera_size=CAMERA_SIZE)
    rays = camera_rays(rig.camera)  # (H, W, 3), camera frame = world frame of synthetic_rig
    t = (PLANE_NORMAL @ PLANE_POINT_MM) / (rays @ PLANE_NORMAL)  # (H, W) mm along each unit ray
    points = t[..., None] * rays  # (H, W, 3)
    local = points @ rig.projector.R.T + rig.projector.T
    projector_px = normalized_to_pixels(distort(local[..., :2] / local[..., 2:3], rig.projector.dist),
                                        rig.projector.K)  # (H, W, 2)
    projector_x = projector_px[..., 0]
    lit = (projector_x >= 0) & (projector_x <= EXTENT_PX - 1)
    if world_pose:
        rig = posed(rig, rotation("x", 20.0) @ rotation("y", -35.0), [120.0, -40.0, 300.0])
    return PlaneScene(rig=rig, points_mm=points, projector_x=projector_x, lit=lit)


def test_scene_is_on_the_projector_and_in_front_of_the_camera():
    scene = plane_scene()
    assert scene.lit.all()  # every pixel sees a fringe: the whole image is a valid scan
    assert 700 < scene.points_mm[..., 2].min() < scene.points_mm[..., 2].max() < 1000


def test_scene_agrees_with_the_per_pixel_reference_triangulation():
    scene = plane_scene()
    rows, cols = np.mgrid[0:120:17, 0:160:23]
    pixels = np.stack([cols.ravel(), rows.ravel()], axis=1).astype(float)  # (M, 2) (u, v)
    points = triangulate_reference(scene.rig, pixels, scene.projector_x[rows, cols].ravel())
    assert np.max(np.abs(points - scene.points_mm[rows, cols].reshape(-1, 3))) < 1e-6


def test_posed_rig_sees_the_same_scene_in_its_world_frame():
    scene, moved = plane_scene(), plane_scene(world_pose=True)
    R_w = rotation("x", 20.0) @ rotation("y", -35.0)
    world = (scene.points_mm[5, 7] - [120.0, -40.0, 300.0]) @ R_w  # X_new = R_w^T (X_old - T_w)
    camera = moved.rig.camera.R @ world + moved.rig.camera.T
    assert np.allclose(camera, scene.points_mm[5, 7], atol=1e-9)
    assert np.allclose(moved.projector_x, scene.projector_x)
