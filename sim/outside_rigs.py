"""Rigs and scenes the project was not built on, for tests and evaluations: one module for every outside-rig generator.

The project develops on the DP-TPU rig (camera f = 2600 px at 640x480, a 912x1140 projector, 6.21 deg, 800 mm)
and trains on :func:`dptpu.sim.rig.wide_rig`. The rigs here come from elsewhere, as a new user's would:

- :func:`outside_rig`: a camera and a projector from the numbers a user gives (camera focal length, baseline,
  toe-in angle, projector panel and focal length); the projector sits to the camera's side, turned in so that both
  optical axes cross at ``baseline / tan(angle)``.
- :func:`random_outside_rig`: such a rig with every number drawn by a seed (focal 1000-3200 px, baseline
  60-250 mm, 6-20 deg, one of three projector panels, small random distortion).
- :func:`issue16_rig`: the outside tester's rig of issue 16 (focal 1800 px, projector 150 mm to the side, turned
  in by 14 deg).
- :class:`EvalRig` and :data:`OUTSIDE_RIGS`: the crossing-axes rigs of ``dptpu eval cloud``
  (:mod:`dptpu.experiments.cloud_eval`), :func:`dptpu.sim.rig.wide_rig`'s construction at other focal lengths,
  angles and distances.
- :class:`MixedPixelRig`: the pinhole pair of the analytic mixed-pixel captures (``tests/mixed_pixel_rigs.py``,
  whose renderer stays independent of ``dptpu.sim``), the projector to the camera's right.
- :func:`spheres_and_plane`: ``n`` spheres in front of a tilted plane (depth edges, self-occlusion, shadows).
- :func:`render_phases`: wrapped phases of any frequencies, rendered with the twin's raycast renderer at ``k x k``
  supersampling and box-averaged down (each camera pixel integrates the scene over its area, so depth edges
  hold mixed pixels), with the paper's additive Gaussian noise and 8-bit quantization; with the ground-truth
  projector column of every pixel.

Everything is seeded; nothing is tuned to one rig. Sizes are small (``~120x90``) so a test renders in seconds.
Moved here from ``tests/outside_rigs.py``, ``tests/mixed_pixel_rigs.py`` and ``experiments/cloud_eval.py`` (which
re-export them) without a change of number: the same seeds give the same rigs (``tests/sim/test_outside_rigs.py``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dptpu.fpp.calibration import DeviceModel, Rig
from dptpu.fpp.phase import wrapped_phase
from dptpu.sim.image_formation import SequenceSpec, quantize, render_frames_float
from dptpu.sim.raycast import trace
from dptpu.sim.rig import resize_camera, wide_rig, working_point
from dptpu.sim.scene_mesh import Material
from dptpu.sim.scenes import Scene
from dptpu.sim.scenes.primitives import plane, sphere
from dptpu.sim.scenes.scene import posed_mesh

__all__ = ["MIXED_PIXEL_PROJECTOR_SIZE", "OUTSIDE_RIGS", "PROJECTOR_PANELS", "SIGMA_2", "EvalRig", "MixedPixelRig",
           "OutsidePhases", "issue16_rig", "outside_rig", "random_outside_rig", "render_phases", "spheres_and_plane"]

#: The paper's 2 sigma camera noise on 8-bit frames, gray levels.
SIGMA_2 = 3.1386
#: Projector panels ``(width, height, fx, fy)`` the random rigs draw from: a DLP4500 (non-square pixels, the
#: project's own), an XGA DMD and a WXGA panel.
PROJECTOR_PANELS = ((912, 1140, 1736.0, 3473.0), (1024, 768, 2200.0, 2200.0), (1280, 800, 1500.0, 1500.0))
_CAMERA_SIZE = (640, 480)


def outside_rig(*, camera_focal_px: float, baseline_mm: float, angle_deg: float,
                panel=PROJECTOR_PANELS[2], camera_k1: float = 0.0, projector_k1: float = 0.0,
                side: int = 1, size=(120, 90)) -> Rig:
    """A rig from a user's numbers: world frame = the camera's, the projector ``baseline_mm`` to the side.

    Parameters
    ----------
    camera_focal_px : float
        Camera focal length in pixels at 640x480 (``K`` is rescaled for ``size``).
    baseline_mm : float
        Distance of the projector's centre from the camera's, along the camera's x axis.
    angle_deg : float
        Toe-in: the projector is turned towards the camera axis by this angle; the axes cross at
        ``baseline_mm / tan(angle_deg)`` on the camera axis.
    panel : (int, int, float, float)
        Projector ``(width, height, fx, fy)`` in projector pixels, principal point at the panel centre.
    camera_k1, projector_k1 : float
        Radial distortion of each lens.
    side : {1, -1}
        +1: the projector sits to the camera's right (+x), -1: to its left.
    size : (int, int)
        Camera ``(width, height)`` of the renders.
    """
    a = np.radians(angle_deg) * side
    R_p = np.array([[np.cos(a), 0.0, np.sin(a)], [0.0, 1.0, 0.0], [-np.sin(a), 0.0, np.cos(a)]])  # turned in
    centre = np.array([side * baseline_mm, 0.0, 0.0])
    f = float(camera_focal_px)
    width, height = _CAMERA_SIZE
    camera = DeviceModel(K=np.array([[f, 0.0, (width - 1) / 2], [0.0, f, (height - 1) / 2], [0.0, 0.0, 1.0]]),
                         dist=np.array([camera_k1, 0.0, 0.0, 0.0, 0.0]), R=np.eye(3), T=np.zeros(3),
                         size=_CAMERA_SIZE)
    pw, ph, pfx, pfy = panel
    projector = DeviceModel(K=np.array([[pfx, 0.0, (pw - 1) / 2], [0.0, pfy, (ph - 1) / 2], [0.0, 0.0, 1.0]]),
                            dist=np.array([projector_k1, 0.0, 0.0, 0.0, 0.0]), R=R_p, T=-R_p @ centre,
                            size=(int(pw), int(ph)))
    return resize_camera(Rig(camera=camera, projector=projector, units="mm"), size)


def issue16_rig(size=(120, 90)) -> Rig:
    """The outside tester's rig of issue 16: camera focal 1800 px, projector 150 mm to the side turned in by
    14 deg (axes cross at 602 mm), a WXGA projector panel."""
    return outside_rig(camera_focal_px=1800.0, baseline_mm=150.0, angle_deg=14.0, size=size)


def random_outside_rig(seed: int, size=(120, 90)) -> Rig:
    """A rig with every number drawn from ``seed``: focal 1000-3200 px, baseline 60-250 mm, toe-in 6-20 deg,
    one of :data:`PROJECTOR_PANELS`, either side, radial distortion within +-0.08."""
    rng = np.random.default_rng([16, seed])
    return outside_rig(camera_focal_px=rng.uniform(1000.0, 3200.0), baseline_mm=rng.uniform(60.0, 250.0),
                       angle_deg=rng.uniform(6.0, 20.0), panel=PROJECTOR_PANELS[rng.integers(len(PROJECTOR_PANELS))],
                       camera_k1=rng.uniform(-0.08, 0.08), projector_k1=rng.uniform(-0.05, 0.05),
                       side=int(rng.choice([-1, 1])), size=size)


def spheres_and_plane(rig: Rig, seed: int = 0, *, spheres: int = 2) -> Scene:
    """``spheres`` spheres in front of a plane tilted 15-35 deg, all sized to the camera's field at the working
    distance ``d``: the plane 1.1-1.25 ``d`` away, sphere radii 6-12 % of the field's width, centres 0.85-0.97 ``d``
    away spread across the field."""
    rng = np.random.default_rng([17, seed])
    centre = working_point(rig)
    d = float(centre[2])
    field = rig.camera.size[0] / rig.camera.K[0, 0] * d  # field width at d, mm
    tilt = np.radians(rng.uniform(15.0, 35.0)) * rng.choice([-1.0, 1.0])
    R_plane = np.array([[np.cos(tilt), 0.0, np.sin(tilt)], [0.0, 1.0, 0.0], [-np.sin(tilt), 0.0, np.cos(tilt)]])
    vertices, triangles, _ = plane((4.0 * field, 4.0 * field), 1)
    meshes = [posed_mesh("plane", vertices, triangles, rotation=R_plane,
                         translation=[centre[0], centre[1], d * rng.uniform(1.1, 1.25)],
                         material=Material(albedo=rng.uniform(0.5, 0.9), roughness=0.9, specular=0.0, ior=1.5))]
    for i in range(spheres):
        radius = field * rng.uniform(0.06, 0.12)
        offset = (i - (spheres - 1) / 2) * field * 0.3 + rng.uniform(-0.05, 0.05) * field
        position = [centre[0] + offset, centre[1] + rng.uniform(-0.15, 0.15) * field, d * rng.uniform(0.85, 0.97)]
        vertices, triangles = sphere(radius, 4)
        meshes.append(posed_mesh(f"sphere{i}", vertices, triangles, translation=position,
                                 material=Material(albedo=rng.uniform(0.5, 0.9), roughness=0.6, specular=0.05,
                                                   ior=1.5)))
    return Scene(meshes=meshes, name="spheres_and_plane", source=f"dptpu.sim.outside_rigs(seed={seed})")


@dataclass(frozen=True, eq=False)
class OutsidePhases:
    """Wrapped phases of one rendered capture and their ground truth.

    Attributes
    ----------
    phases : dict of float -> ndarray (H, W) float64
        Wrapped phase of each frequency, ``[0, 2pi)``, Eq. (2) on the quantized frames.
    modulation : dict of float -> ndarray (H, W) float64
        Modulation ``B`` of each frequency, gray levels.
    projector_x : ndarray (H, W) float64
        Projector column of each pixel's centre ray (0-based), NaN where not lit.
    valid : ndarray (H, W) bool
        The pixel's centre ray hits a lit surface.
    extent : float
        Projector width, pixels (the fringe axis is x).
    """

    phases: dict
    modulation: dict
    projector_x: np.ndarray
    valid: np.ndarray
    extent: float

    def order(self, frequency: float) -> np.ndarray:
        """True fringe order ``floor(f x_p / W)`` (H, W) int64, -1 where not valid."""
        with np.errstate(invalid="ignore"):
            k = np.floor(frequency * self.projector_x / self.extent)
        return np.where(self.valid, k, -1).astype(np.int64)


def render_phases(rig: Rig, scene: Scene, frequencies, *, steps: int = 3, noise_dn: float = 0.0,
                  supersample: int = 3, seed: int = 0) -> OutsidePhases:
    """Render ``steps``-step fringes of each frequency (x axis, Eq. (1)) and decode their wrapped phases.

    Parameters
    ----------
    rig, scene
        From :func:`outside_rig` / :func:`random_outside_rig` and :func:`spheres_and_plane` (or any).
    frequencies : iterable of float
        Periods across the projector width.
    steps : int
        Phase steps per frequency (3: the paper's inputs; 12: its labels).
    noise_dn : float
        Std of additive Gaussian camera noise, gray levels, before 8-bit quantization (:data:`SIGMA_2`).
    supersample : int
        ``k``: the camera is traced at ``k`` times the resolution and each pixel averages its ``k x k`` rays.
    seed : int
        Seed of the noise.
    """
    width, height = rig.camera.size
    k = int(supersample)
    centre = trace(rig, scene.meshes)
    fine_rig = resize_camera(rig, (width * k, height * k)) if k > 1 else rig
    fine = trace(fine_rig, scene.meshes) if k > 1 else centre
    rng = np.random.default_rng([18, seed])
    phases, modulation = {}, {}
    for f in frequencies:
        frames = render_frames_float(fine_rig, fine, [SequenceSpec(frequency=float(f), steps=int(steps))],
                                     effects=[], seed=seed)[0]
        frames = frames.reshape(len(frames), height, k, width, k).mean(axis=(2, 4))
        frames = frames + noise_dn * rng.standard_normal(frames.shape)
        decoded = wrapped_phase(quantize(frames, 8))
        phases[float(f)] = decoded.phase.astype(np.float64)
        modulation[float(f)] = decoded.modulation.astype(np.float64)
    valid = centre.lit.copy()
    projector_x = np.where(valid, centre.projector_xy[..., 0], np.nan)
    return OutsidePhases(phases=phases, modulation=modulation, projector_x=projector_x, valid=valid,
                         extent=float(rig.projector.size[0]))


# -- the rigs of dptpu eval cloud ------------------------------------------------------------------------------------

@dataclass(frozen=True)
class EvalRig:
    """A crossing-axes rig (:func:`dptpu.sim.rig.wide_rig`'s construction: the DLP4500 projector to the camera's left,
    turned by ``angle_deg`` so the axes cross at ``distance_mm``; baseline ``distance_mm * tan(angle_deg)``)."""

    name: str
    focal_px: float  # camera focal length at 640x480
    angle_deg: float
    distance_mm: float

    def rig(self, size: tuple[int, int]) -> Rig:
        return resize_camera(wide_rig(distance_mm=self.distance_mm, angle_deg=self.angle_deg,
                                      camera_focal_px=self.focal_px), size)

    @property
    def baseline_mm(self) -> float:
        return self.distance_mm * math.tan(math.radians(self.angle_deg))


#: Rigs no shipped model was trained on (training: nominal 2600 px / 6.21 deg / 800 mm and wide 1000 px / 8 deg /
#: 700 mm): issue #16's outside rig (1800 px, 150 mm baseline, 14 deg), a long narrow one and a short wide one.
OUTSIDE_RIGS = (EvalRig("f1800-b150-14deg", 1800.0, 14.0, 601.6), EvalRig("f1300-b79-5deg", 1300.0, 5.0, 900.0),
                EvalRig("f2400-b164-20deg", 2400.0, 20.0, 450.0))


# -- the rig of the analytic mixed-pixel captures --------------------------------------------------------------------

#: Projector panel of :class:`MixedPixelRig`, pixels.
MIXED_PIXEL_PROJECTOR_SIZE = (912, 1140)

@dataclass(frozen=True)
class MixedPixelRig:
    """Camera and projector geometry (mm, pixels) of the analytic mixed-pixel captures: a pinhole camera at the
    world origin looking along +z, a pinhole projector ``baseline_mm`` to its right turned in by ``toe_in_deg``."""

    camera_size: tuple[int, int] = (160, 120)
    camera_focal_px: float = 600.0
    projector_focal_px: float = 1400.0
    baseline_mm: float = 150.0
    toe_in_deg: float = 14.0
    distance_mm: float = 600.0  # the plane's distance along the camera axis

    def rig(self) -> Rig:
        w, h = self.camera_size
        camera = DeviceModel(K=np.array([[self.camera_focal_px, 0, (w - 1) / 2], [0, self.camera_focal_px,
                                         (h - 1) / 2], [0, 0, 1]], dtype=np.float64),
                             dist=np.zeros(5), R=np.eye(3), T=np.zeros(3), size=(w, h))
        a = np.deg2rad(self.toe_in_deg)
        R = np.array([[np.cos(a), 0.0, np.sin(a)], [0.0, 1.0, 0.0], [-np.sin(a), 0.0, np.cos(a)]])
        centre = np.array([self.baseline_mm, 0.0, 0.0])
        pw, ph = MIXED_PIXEL_PROJECTOR_SIZE
        projector = DeviceModel(K=np.array([[self.projector_focal_px, 0, (pw - 1) / 2], [0, self.projector_focal_px,
                                            (ph - 1) / 2], [0, 0, 1]], dtype=np.float64),
                                dist=np.zeros(5), R=R, T=-R @ centre, size=(pw, ph))
        return Rig(camera=camera, projector=projector, units="mm")
