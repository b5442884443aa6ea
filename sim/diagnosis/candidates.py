"""Candidate effects fitted with the twin in the loop, each scored against the baseline twin.

Photometric candidates (intensity domain, needs raw frames): each effect of the twin's vocabulary
(docs/effects.md) that changes what a pixel records is switched on with one free parameter (its main one; the
others fixed at "no random part"), and the parameter is fitted by least squares on the intensity residual
``measured - s_q * twin`` (:func:`dptpu.sim.diagnosis.forward.intensity_residual`): a coarse grid over the
parameter's range, then a bounded Brent search around the best grid point. ``residual_before`` /
``residual_after`` are the RMS of the residual (DN) without / with the effect.

Geometric candidates (phase domain, works on a phase file too): ``lens_distortion`` adds a camera ``k1`` to the
rig and refits it with the pose (:func:`dptpu.sim.diagnosis.registration.register`); residuals are the
projector-coordinate RMS (projector px).

``sensor_noise`` is not fitted by least squares (noise does not change the mean): see
:mod:`dptpu.sim.diagnosis.noise`.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import minimize_scalar

from dptpu.fpp.calibration import DeviceModel, Rig

from .flicker import fit_drift_with_flicker
from .forward import PixelSet, intensity_residual
from .registration import Registration, register
from .saturation import fit_saturation
from .selection import delta_bic, gain

__all__ = ["Candidate", "PHOTOMETRIC", "NOT_IDENTIFIABLE", "not_identifiable", "fit_photometric",
           "fit_one_parameter", "fit_lens_distortion", "add_camera_k1", "fit_geometric_extra"]


@dataclass(frozen=True)
class Candidate:
    """A photometric candidate: effect ``name``, its fitted parameter ``main`` in ``bounds`` (``grid`` points
    first, ``log`` spacing for a scale-like parameter), ``fixed`` other parameters, ``neutral`` the value at which
    the effect does nothing (None: the effect switched off). ``values``: a discrete parameter, each value tried
    (no search between them). ``per_pixel_gain=False``: scored with one gain for all pixels (an effect a free
    per-pixel gain would absorb). ``needs``: what the pixel set must carry (``"reference"``: a registered
    reference object, not the data's own phase)."""

    name: str
    main: str
    bounds: tuple
    neutral: float | None
    fixed: dict
    grid: int = 9
    log: bool = False
    values: tuple = ()
    per_pixel_gain: bool = True
    needs: str | None = None

    def effect(self, value) -> dict:
        value = int(value) if self.values and float(value).is_integer() else float(value)
        return {self.name: {self.main: value, **self.fixed}}


#: The photometric vocabulary fitted here (docs/sim-to-real.md gives each detection limit).
PHOTOMETRIC = (
    Candidate("projector_gamma", "gamma", (0.4, 3.5), 1.0, {}, log=True),
    Candidate("projector_defocus", "sigma_px", (0.0, 4.0), 0.0, {}),
    Candidate("ambient_light", "level", (0.0, 0.6), 0.0, {}),
    Candidate("intensity_drift", "rate_per_frame", (-0.05, 0.05), 0.0, {"sigma": 0.0}),
    Candidate("phase_shift_error", "scale", (0.85, 1.15), 1.0, {"sigma_rad": 0.0}),
    Candidate("saturation", "exposure_gain", (1.0, 3.0), 1.0, {}),
    Candidate("projector_pixelation", "quantize_bits", (0, 10), None, {}, values=(0, 4, 5, 6, 7, 8, 10),
              needs="reference"),
    Candidate("vignetting", "k1", (-0.6, 0.6), 0.0, {"k2": 0.0}, per_pixel_gain=False, needs="reference"),
    Candidate("camera_defocus", "sigma_px", (0.0, 3.0), 0.0, {}, grid=5, needs="reference"),
)

#: Why an effect cannot be fitted from the data's own phase (self-reference) or from a phase file.
NOT_IDENTIFIABLE = {
    "self": {
        "projector_pixelation": "the reference phase is the data's own: it holds the staircase already, so the "
                                "model coordinate is rounded the same way with the effect on or off",
        "vignetting": "the reflectance factor is each pixel's own mean level: it holds the vignetting already",
        "camera_defocus": "the reference phase and level are the blurred data's own; on a smooth surface the "
                          "blur only lowers the modulation, which the data-derived factor cannot tell from the "
                          "projector's",
        "motion": "no geometry: the coordinate change a motion causes depends on the surface, which "
                  "self-reference does not know",
    },
    "phase": {
        "projector_pixelation": "a phase file: raw frames needed (the candidates are fitted on the intensities)",
        "vignetting": "a phase file: vignetting scales background and modulation together, which leaves the "
                      "phase unchanged",
        "camera_defocus": "a phase file: on a smooth surface the blur only lowers the modulation, which leaves "
                          "a 12-step phase unchanged (the edge band shows where it mixes phases)",
        "motion": "a phase file: raw frames needed (the motion shows in the change from frame to frame)",
    },
}


def not_identifiable(name: str, why: str) -> dict:
    """The report entry of a candidate the data cannot show (never named), with the reason."""
    return {"name": name, "parameters": {}, "residual_before": None, "residual_after": None, "gain": 0.0,
            "named": False, "evidence": {"domain": "none", "unit": "", "values": 0, "parameters": 0,
                                         "delta_bic": 0.0, "identifiable": False, "reason": why}}


def _rss(pixels: PixelSet, effects, refine: int, per_pixel_gain: bool = True) -> float:
    residual, _, _ = intensity_residual(pixels, effects, refine=refine, per_pixel_gain=per_pixel_gain)
    return float(sum(np.sum(r * r) for r in residual))


def fit_photometric(pixels: PixelSet, candidate: Candidate, *, base=(), refine: int = 1,
                    rss_before: float | None = None) -> dict:
    """Fit ``candidate`` on top of ``base`` effects; returns an effect entry (report.json).

    Most candidates are one parameter on a grid (:func:`fit_one_parameter`); ``saturation`` clips after the
    per-pixel gain (:mod:`.saturation`), and ``intensity_drift`` adds its per-frame random gain when the frames
    show one (:mod:`.flicker`)."""
    if rss_before is None and candidate.per_pixel_gain:
        rss_before = _rss(pixels, list(base), refine)
    if candidate.name == "saturation":
        assert rss_before is not None
        return fit_saturation(pixels, base=base, refine=refine, rss_before=rss_before)
    entry = fit_one_parameter(pixels, candidate, base=base, refine=refine, rss_before=rss_before)
    if candidate.name == "intensity_drift":
        assert rss_before is not None
        entry = fit_drift_with_flicker(pixels, entry, base=base, refine=refine, rss_before=rss_before)
    return entry


def fit_one_parameter(pixels: PixelSet, candidate: Candidate, *, base=(), refine: int = 1,
                      rss_before: float | None = None) -> dict:
    """Fit ``candidate``'s main parameter on a grid, then by a bounded Brent search, on top of ``base``.

    ``rss_before`` (the baseline with a per-pixel gain) is recomputed for a candidate scored with one gain."""
    n = pixels.values
    per_pixel = candidate.per_pixel_gain
    if rss_before is None or not per_pixel:
        rss_before = _rss(pixels, list(base), refine, per_pixel)

    def objective(value):
        return _rss(pixels, list(base) + [candidate.effect(value)], refine, per_pixel)

    lo, hi = candidate.bounds
    if candidate.values:
        grid = np.asarray(candidate.values, dtype=np.float64)
    elif candidate.log:
        grid = np.geomspace(lo, hi, candidate.grid)
    else:
        grid = np.linspace(lo, hi, candidate.grid)
    if candidate.neutral is not None:
        grid = np.unique(np.append(grid, candidate.neutral))
    values = np.array([objective(v) for v in grid])
    best = int(np.argmin(values))
    left, right = grid[max(best - 1, 0)], grid[min(best + 1, len(grid) - 1)]
    value, rss = float(grid[best]), float(values[best])
    if right > left and not candidate.values:
        solution = minimize_scalar(objective, bounds=(left, right), method="bounded",
                                   options={"xatol": 1e-4 * (hi - lo)})
        if solution.fun < rss:
            value, rss = float(solution.x), float(solution.fun)
    before, after = float(np.sqrt(rss_before / n)), float(np.sqrt(rss / n))
    evidence = {"domain": "intensity", "unit": "DN", "values": n, "parameters": 1,
                "delta_bic": delta_bic(rss_before, rss, n, 1)}
    if not per_pixel:
        evidence["gain_model"] = "one gain for all pixels"
    return {"name": candidate.name, "parameters": dict(next(iter(candidate.effect(value).values()))),
            "residual_before": before, "residual_after": after, "gain": gain(before, after), "evidence": evidence}


def add_camera_k1(rig: Rig, extra) -> Rig:
    """The rig with ``extra[0]`` added to the camera's ``k1`` (the ``lens_distortion`` effect's ``camera``)."""
    camera = rig.camera
    dist = camera.dist.copy()
    dist[0] += float(extra[0])
    return replace(rig, camera=DeviceModel(K=camera.K, dist=dist, R=camera.R, T=camera.T, size=camera.size))


def _phase_entry(name, parameters, baseline, fitted, parameters_count, **evidence) -> dict:
    mask = baseline.mask & fitted.mask
    n = int(mask.sum())
    rss0 = float(np.sum(baseline.residual_px[mask] ** 2))
    rss1 = float(np.sum(fitted.residual_px[mask] ** 2))
    before, after = float(np.sqrt(rss0 / n)), float(np.sqrt(rss1 / n))
    return {"name": name, "parameters": parameters, "residual_before": before, "residual_after": after,
            "gain": gain(before, after),
            "evidence": {"domain": "phase", "unit": "projector px", "values": n, "parameters": parameters_count,
                         "delta_bic": delta_bic(rss0, rss1, n, parameters_count), **evidence}}


def fit_geometric_extra(rig: Rig, reference, measured_x, baseline) -> list[dict]:
    """Phase-domain explanations outside the twin's effect vocabulary, reported for the record (never a cause,
    never in the extended rig): ``sphere_diameter`` (the apparent sphere is smaller or larger: volume
    scattering under the surface, a scale error of the calibration) and ``projector_offset`` (a constant
    projector-coordinate offset: a pixel-centre convention, a phase offset)."""
    out = []
    if reference.kind == "sphere":
        fitted = register(rig, reference, measured_x, baseline.mask, pose0=baseline.pose, free_diameter=True)
        out.append(_phase_entry("sphere_diameter", {"diameter": fitted.diameter,
                                                    "certified": reference.diameter}, baseline, fitted, 1,
                                outside_vocabulary=True))
    fitted = register(rig, reference, measured_x, baseline.mask, pose0=baseline.pose, free_offset=True)
    out.append(_phase_entry("projector_offset", {"offset_px": fitted.offset_px}, baseline, fitted, 1,
                            outside_vocabulary=True))
    return out


def fit_lens_distortion(rig: Rig, reference, measured_x, baseline: Registration) -> tuple[dict, Registration]:
    """Camera ``k1`` the calibration lacks, fitted with the pose (phase domain). Returns the entry and the
    :class:`~dptpu.sim.diagnosis.registration.Registration` with it."""
    fitted = register(rig, reference, measured_x, baseline.mask, rig_of=add_camera_k1, extra0=[0.0],
                      pose0=baseline.pose)
    mask = baseline.mask & fitted.mask
    n = int(mask.sum())
    rss0 = float(np.sum(baseline.residual_px[mask] ** 2))
    rss1 = float(np.sum(fitted.residual_px[mask] ** 2))
    before, after = float(np.sqrt(rss0 / n)), float(np.sqrt(rss1 / n))
    k1 = float(fitted.extra[0])
    entry = {"name": "lens_distortion", "parameters": {"camera": [k1, 0.0, 0.0, 0.0, 0.0],
                                                         "projector": [0.0] * 5},
             "residual_before": before, "residual_after": after, "gain": gain(before, after),
             "evidence": {"domain": "phase", "unit": "projector px", "values": n, "parameters": 1,
                          "delta_bic": delta_bic(rss0, rss1, n, 1), "camera_k1": k1}}
    return entry, fitted
