"""Our twin against the paper's twin on the standard sphere (docs/twin-validation.md).

The paper rendered a virtual standard sphere (diameter 50.8082 mm) in its Blender twin, with the twin calibration
(``CamCalibResult_sim.mat``, ``PrjCalibResult_sim.mat``), and published the absolute phase
(``standardball_phase_sim.mat``, f = 96 periods across the 912-px projector width). Here:

1. the sphere's pose is fitted to that phase map: the centre (radius fixed at the certified one) that makes our
   model's projector coordinate of each pixel (camera ray with distortion -> ray-sphere hit -> projector model with
   distortion) match the published one in least squares (optionally with a constant projector offset ``dx``);
2. our raycast twin renders the sphere mesh (:func:`dptpu.sim.scenes.sphere_scene`, 7 subdivisions: facets within
   0.45 um of the sphere) at that pose; its ground-truth absolute phase is compared with the paper's on the pixels
   valid in both: RMS, bias, a plane fitted over the image, and the radial profile on the sphere's image;
3. both phase maps are reconstructed with the paper's method and ours (:mod:`dptpu.fpp.real_sphere`) and their
   sphere-fit RMS compared with the paper's 28.256 um.

``python -m dptpu.sim.twin_validation [DATA_DIR]`` prints the report as JSON.
"""
from __future__ import annotations

import json
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from dptpu.fpp import real_sphere
from dptpu.fpp.calibration import DeviceModel, Rig
from dptpu.fpp.fitting import fit_sphere
from dptpu.fpp.measured_data import shared_data_dir
from dptpu.fpp.triangulate import Triangulator, camera_rays, projector_coordinate

from .raycast import project_to_projector, trace
from .scenes import sphere_scene

__all__ = ["sphere_projector_x", "fit_sphere_pose", "phase_difference_report", "validate"]

RADIUS_MM = real_sphere.SPHERE_DIAMETER_MM / 2.0
FREQUENCY = real_sphere.FREQUENCY
WIDTH = real_sphere.PROJECTOR_SIZE[0]
PX_TO_RAD = 2.0 * np.pi * FREQUENCY / WIDTH  # absolute phase per projector pixel


def without_distortion(rig: Rig) -> Rig:
    """The rig with zero distortion on both devices (a pure pinhole twin)."""
    def pinhole(device: DeviceModel) -> DeviceModel:
        return DeviceModel(K=device.K, dist=np.zeros(5), R=device.R, T=device.T, size=device.size)

    return replace(rig, camera=pinhole(rig.camera), projector=pinhole(rig.projector))


def sphere_projector_x(rig: Rig, center, radius: float = RADIUS_MM, *, rays=None, extend: bool = False) -> np.ndarray:
    """Projector column of the analytic sphere's first hit per camera ray (P,) (rays (P, 3) default: every pixel
    of the rig's camera, with distortion); NaN where the ray misses, or with ``extend`` the column of the ray's
    point closest to the sphere (a continuous extension past the silhouette, for fitting)."""
    rays = camera_rays(rig.camera).reshape(-1, 3) if rays is None else rays
    origin = rig.camera.center
    oc = origin - np.asarray(center, dtype=np.float64)
    b = rays @ oc
    disc = b * b - (oc @ oc - radius * radius)
    t = -b - np.sqrt(np.maximum(disc, 0.0))
    xy, _ = project_to_projector(rig, origin + rays * t[:, None])
    return xy[:, 0] if extend else np.where(disc > 0, xy[:, 0], np.nan)


def fit_sphere_pose(rig: Rig, projector_x: np.ndarray, *, with_offset: bool = False, offset_px: float = 0.0,
                    radius: float | None = RADIUS_MM):
    """Sphere centre (3,) (and projector offset ``dx``) whose rendering best matches ``projector_x`` (H, W).

    Minimizes ``sum (x_model(c, r) + dx - x_measured)^2`` over the finite pixels of ``projector_x``; ``dx`` is
    fitted when ``with_offset``, else fixed at ``offset_px``; ``radius=None`` fits the radius too. The start is a
    fixed-radius geometric fit of the triangulated points. Returns ``(center, radius, dx, rms_px)``.
    """
    valid = np.isfinite(projector_x)
    rays = camera_rays(rig.camera).reshape(-1, 3)[valid.ravel()]
    target = projector_x[valid]
    start = fit_sphere(Triangulator(rig).points(np.where(valid, projector_x, 0.0))[valid], radius=RADIUS_MM).center
    free_radius = radius is None
    if free_radius:  # start from the certified-radius fit at the same offset (the silhouette makes it non-smooth)
        start, *_ = fit_sphere_pose(rig, projector_x, with_offset=with_offset, offset_px=offset_px)

    def unpack(p):
        r = p[3] if free_radius else radius
        dx = p[-1] if with_offset else offset_px
        return p[:3], r, dx

    def residuals(p):
        center, r, dx = unpack(p)
        return sphere_projector_x(rig, center, r, rays=rays, extend=True) + dx - target

    x0 = list(start) + ([RADIUS_MM] if free_radius else []) + ([offset_px] if with_offset else [])
    solution = least_squares(residuals, np.asarray(x0))
    r = residuals(solution.x)
    center, fitted_radius, dx = unpack(solution.x)
    return center, float(fitted_radius), float(dx), float(np.sqrt(np.mean(r * r)))


def phase_difference_report(ours: np.ndarray, theirs: np.ndarray) -> dict[str, Any]:
    """Statistics of ``ours - theirs`` (absolute phase maps (H, W), radians, NaN invalid): RMS, bias, a plane
    ``a + b u + c v`` over the image (its coefficients in projector px and px per 100 camera px), the RMS left after
    the plane, and the RMS in the interior and the outer band of the sphere's image."""
    both = np.isfinite(ours) & np.isfinite(theirs)
    diff = (ours - theirs)[both] / PX_TO_RAD  # projector pixels
    v, u = np.nonzero(both)
    A = np.column_stack([np.ones(len(u)), (u - u.mean()) / 100.0, (v - v.mean()) / 100.0])
    coefficients, *_ = np.linalg.lstsq(A, diff, rcond=None)
    left = diff - A @ coefficients
    centre = np.array([u.mean(), v.mean()])
    r = np.hypot(u - centre[0], v - centre[1])
    r /= r.max()
    inner, outer = r < 0.7, r >= 0.9
    return {
        "pixels": int(both.sum()), "only_ours": int((np.isfinite(ours) & ~np.isfinite(theirs)).sum()),
        "only_theirs": int((~np.isfinite(ours) & np.isfinite(theirs)).sum()),
        "rms_px": round(float(np.sqrt(np.mean(diff ** 2))), 4),
        "rms_rad": round(float(np.sqrt(np.mean(diff ** 2)) * PX_TO_RAD), 4),
        "mean_px": round(float(diff.mean()), 4),
        "plane_px": {"offset": round(float(coefficients[0]), 4), "per_100px_u": round(float(coefficients[1]), 4),
                     "per_100px_v": round(float(coefficients[2]), 4)},
        "rms_after_plane_px": round(float(np.sqrt(np.mean(left ** 2))), 4),
        "rms_inner_px": round(float(np.sqrt(np.mean(diff[inner] ** 2))), 4),
        "rms_outer_band_px": round(float(np.sqrt(np.mean(diff[outer] ** 2))), 4),
    }


def _render_phase(rig: Rig, center, subdivisions: int = 7) -> np.ndarray:
    samples = trace(rig, sphere_scene(rig, center=center, subdivisions=subdivisions))
    return np.where(samples.lit, samples.projector_xy[..., 0] * PX_TO_RAD, np.nan)


def _reconstructions(rig: Rig, refined: Rig | None, phase: np.ndarray) -> dict[str, float]:
    paper = real_sphere.paper_reconstruction(rig, phase)
    valid = np.isfinite(phase)
    same = fit_sphere(Triangulator(rig).points(projector_coordinate(phase, FREQUENCY, WIDTH))[valid])
    out = {"paper_method_um": round(paper.rms_um, 3), "paper_method_radius_mm": round(paper.radius_mm, 4),
           "view1_rig_with_distortion_um": round(same.rms * 1e3, 3),
           "view1_rig_with_distortion_radius_mm": round(same.radius, 4)}
    if refined is not None:
        own_all, own_edge = real_sphere.own_reconstruction(refined, phase)
        out.update({"ours_um": round(own_all.rms_um, 3), "ours_radius_mm": round(own_all.radius_mm, 4),
                    "ours_edge_band_removed_um": round(own_edge.rms_um, 3)})
    return out


def _fit_entry(center, radius, dx, rms) -> dict[str, Any]:
    return {"center_mm": [round(float(c), 3) for c in center], "radius_mm": round(radius, 4),
            "offset_px": round(dx, 3), "rms_px": round(rms, 4)}


def validate(data_dir, *, full: bool = True) -> dict[str, Any]:
    """The whole comparison (module docstring) as a JSON-ready dict; ``full=False`` keeps the essentials (one pose
    fit, one render at 6 subdivisions: 1.8 um facets) for tests."""
    data_dir = Path(data_dir)
    rig = real_sphere.load_rig(data_dir, "twin")
    refined = real_sphere.load_rig(data_dir, "twin", relative_pose="all-views") if full else None
    theirs = real_sphere.load_phase(data_dir, "twin")
    x_theirs = projector_coordinate(theirs, FREQUENCY, WIDTH)
    fits: dict[str, dict[str, Any]] = {}
    renders: dict[str, dict[str, Any]] = {}
    report: dict[str, Any] = {"paper_figure_um": real_sphere.PAPER_FIGURES_UM[("twin", "twin")], "fits": fits,
                              "renders": renders}
    models = (("distortion", rig), ("pinhole", without_distortion(rig))) if full else (("distortion", rig),)
    for label, model in models:
        fits[label] = _fit_entry(*fit_sphere_pose(model, x_theirs))
        ours = _render_phase(model, fits[label]["center_mm"], 7 if full else 6)
        entry = phase_difference_report(ours, theirs)
        entry["reconstruction_ours"] = _reconstructions(rig, refined, ours)
        renders[label] = entry
    report["reconstruction_theirs"] = _reconstructions(rig, refined, theirs)
    if not full:
        return report
    # a constant projector offset: fitted, and fixed at 0, 0.5, 1 px with the radius free
    fits["distortion+offset"] = _fit_entry(*fit_sphere_pose(rig, x_theirs, with_offset=True))
    for offset in (0.0, 0.5, 1.0):
        fits[f"distortion_offset_{offset:g}"] = _fit_entry(*fit_sphere_pose(rig, x_theirs, offset_px=offset))
        fits[f"distortion_offset_{offset:g}_free_radius"] = _fit_entry(
            *fit_sphere_pose(rig, x_theirs, offset_px=offset, radius=None))
    # the real calibration against the twin phase: the "+1 px" finding
    real = real_sphere.load_rig(data_dir, "real")
    for label, model in (("real_pinhole", without_distortion(real)), ("real_distortion", real)):
        fits[f"{label}+offset"] = _fit_entry(*fit_sphere_pose(model, x_theirs, with_offset=True))
    return report


if __name__ == "__main__":  # pragma: no cover
    folder = Path(sys.argv[1]) if len(sys.argv) > 1 else shared_data_dir() / "dptpu-sphere"
    print(json.dumps(validate(folder), indent=2))
