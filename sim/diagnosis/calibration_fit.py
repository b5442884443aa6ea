"""The ``calibration_error`` candidate: the rig the data were taken with, fitted against the reference object.

The effect (:mod:`dptpu.sim.effects.calibration`) has 12 components; one view of a sphere or a plane cannot
tell them all apart (the projector's ``cy`` does nothing to an x-fringe coordinate, and a turn of the projector
about its vertical axis is nearly a shift of its ``cx``). So the components are chosen by forward stepwise
selection, each step the registration (:func:`dptpu.sim.diagnosis.registration.register`: the reference's pose
and the components chosen so far, least squares on the measured projector coordinate) with one more component
free, the one that lowers the residual most kept while it passes both criteria of
:func:`dptpu.sim.diagnosis.selection.significant` against the previous step (``dBIC > 10`` for one more
parameter and at least 5 % less residual RMS) and stays within what a calibration can plausibly be off
(:data:`PLAUSIBLE_UNITS`; beyond it the pose and a component are absorbing something else, such as an edge
effect reaching into the interior), up to :data:`MAX_COMPONENTS`. The components left out stay at
"no error"; the fitted rig is the given rig with the chosen ones (``corrected_rig.yaml`` of the report).

Parameters are fitted in units of their typical size (:data:`COMPONENT_UNITS`, translation in units of the
camera-projector baseline), so the least-squares steps are comparable.
"""
from __future__ import annotations

import numpy as np

from dptpu.fpp.calibration import Rig
from dptpu.fpp.triangulate import camera_rays
from dptpu.sim.effects.calibration import calibration_params, calibration_vector, miscalibrated_rig

from .reference import surface_hits
from .registration import Registration, register
from .selection import MIN_DELTA_BIC, MIN_GAIN, delta_bic, gain

__all__ = ["COMPONENTS", "MAX_COMPONENTS", "PLAUSIBLE_UNITS", "fit_calibration_error", "component_value",
           "NOT_IDENTIFIABLE_ON_SCENE"]

#: Components of the 12-vector (:func:`dptpu.sim.effects.calibration.calibration_vector`) the stepwise fit may
#: free: name, index, unit (``None``: the baseline length). The projector's ``cy`` (index 11) moves only the
#: coordinate across the fringes, which an x-fringe capture does not measure; its ``cx`` (index 10) is a turn
#: of the projector about its vertical axis to first order (``fx tan(angle)`` px): freed together, the two
#: cancel each other and absorb what is not a calibration error, so only the turn is fitted.
COMPONENTS = (("rotation_x_deg", 0, 0.1), ("rotation_y_deg", 1, 0.1), ("rotation_z_deg", 2, 0.1),
              ("translation_x", 3, None), ("translation_y", 4, None), ("translation_z", 5, None),
              ("camera_focal_scale", 6, 1e-3), ("projector_focal_scale", 7, 1e-3),
              ("camera_cx_px", 8, 1.0), ("camera_cy_px", 9, 1.0))
#: The largest error a calibration can plausibly hold, per component, in its units: 2 deg of rotation, 10 % of
#: the baseline, 3 % of focal length, 30 px of principal point. A step whose fit leaves these bounds is
#: something else (the pose and a calibration component absorbing an edge or a filter effect) and ends the
#: selection.
PLAUSIBLE_UNITS = np.array([20.0, 20.0, 20.0, 10.0, 10.0, 10.0, 30.0, 30.0, 30.0, 30.0])
#: At most this many components are freed (one view of one object shows a few of the 10).
MAX_COMPONENTS = 4
#: Why a scene reference does not fit it (reported, never named).
NOT_IDENTIFIABLE_ON_SCENE = ("a scene reference: its pose is registered by ICP; the calibration is fitted against an "
                             "analytic sphere or plane")
#: Relative size of one translation unit: a hundredth of the camera-projector baseline.
TRANSLATION_UNIT_OF_BASELINE = 0.01


def _units(rig: Rig) -> np.ndarray:
    baseline = float(np.linalg.norm(rig.camera.center - rig.projector.center))
    return np.array([TRANSLATION_UNIT_OF_BASELINE * baseline if unit is None else unit
                     for _, _, unit in COMPONENTS])


def component_value(params: dict, name: str) -> float:
    """One component (a name of :data:`COMPONENTS`) of a ``calibration_error`` parameter dict."""
    index = {n: i for n, i, _ in COMPONENTS}[name]
    return float(calibration_vector(params)[index])


def _rss(baseline: Registration, fitted: Registration) -> tuple[float, float, int]:
    mask = baseline.mask & fitted.mask
    return (float(np.sum(baseline.residual_px[mask] ** 2)), float(np.sum(fitted.residual_px[mask] ** 2)),
            int(mask.sum()))


def _best_next_component(rig, reference, current: Registration, chosen, values, units, rig_of_for):
    """The component whose freeing lowers the residual most, by a Gauss-Newton step from ``current`` (pose,
    the chosen components and the candidate free; forward differences of the model coordinate); None when none
    is left."""
    left = [k for k in range(len(COMPONENTS)) if k not in chosen]
    if not left:
        return None
    mask = current.mask
    residual = current.residual_px[mask]  # model - measured

    def model(pose, extra, k=None, step=0.0):
        extra = list(extra) + ([step] if k is not None else [])
        fitted = rig_of_for(chosen + ([k] if k is not None else []))(rig, np.asarray(extra))
        rays = camera_rays(fitted.camera)[mask]
        return surface_hits(fitted, reference.kind, pose, diameter=reference.diameter, rays=rays,
                            extend=True).projector_xy[..., 0]

    pose = np.asarray(current.pose, dtype=np.float64)
    x0 = model(pose, values)
    step = 1e-3
    columns = []
    for i in range(len(pose)):
        scale = 1.0 if reference.kind == "sphere" else (1e-3 if i < 2 else 1.0)
        moved = pose.copy()
        moved[i] += step * scale
        columns.append((model(moved, values) - x0) / step)
    for i in range(len(values)):
        moved_values = list(values)
        moved_values[i] += step
        columns.append((model(pose, moved_values) - x0) / step)
    fixed = np.column_stack(columns)
    best, best_rss = None, np.inf
    for k in left:
        design = np.column_stack([fixed, (model(pose, values, k, step) - x0) / step])
        design = np.where(np.isfinite(design), design, 0.0)
        solution, *_ = np.linalg.lstsq(design, -residual, rcond=None)
        rss = float(np.sum((residual + design @ solution) ** 2))
        if rss < best_rss:
            best, best_rss = k, rss
    return best


def fit_calibration_error(rig: Rig, reference, measured_x: np.ndarray, baseline: Registration, *,
                          max_components: int = MAX_COMPONENTS) -> tuple[dict, Registration]:
    """Fit the ``calibration_error`` components (module docstring) with the reference's pose.

    Parameters
    ----------
    rig : Rig
        The given calibration.
    reference : Reference
        A sphere or a plane.
    measured_x : ndarray (H, W)
        Measured projector coordinate, projector px, NaN invalid.
    baseline : Registration
        The registration with the given rig (its mask is the fitted pixels).

    Returns
    -------
    entry : dict
        The report entry (phase domain; ``evidence.components`` the chosen ones, in order, with each step's
        residual RMS and dBIC).
    fitted : Registration
        The registration with the fitted rig (``fitted.rig``): ``baseline`` when no component is chosen.
    """
    units = _units(rig)

    def rig_of_for(chosen):
        def rig_of(base: Rig, extra) -> Rig:
            vector = np.zeros(12)
            for k, value in zip(chosen, extra):
                vector[COMPONENTS[k][1]] = value * units[k]
            return miscalibrated_rig(base, calibration_params(vector))
        return rig_of

    chosen: list[int] = []
    current: Registration = baseline
    values: list[float] = []
    steps: list[dict] = []
    implausible: list[dict] = []
    while len(chosen) < max_components:
        k = _best_next_component(rig, reference, current, chosen, values, units, rig_of_for)
        if k is None:
            break
        fitted = register(rig, reference, measured_x, baseline.mask, rig_of=rig_of_for(chosen + [k]),
                          extra0=values + [0.0], pose0=current.pose)
        before, after, n = _rss(current, fitted)
        rms_before, rms_after = np.sqrt(before / n), np.sqrt(after / n)
        step_bic = delta_bic(before, after, n, 1)
        if not (step_bic > MIN_DELTA_BIC and gain(rms_before, rms_after) > MIN_GAIN):
            break
        outside = [COMPONENTS[c][0] for c, v in zip(chosen + [k], fitted.extra) if abs(v) > PLAUSIBLE_UNITS[c]]
        if outside:
            implausible.append({"component": COMPONENTS[k][0], "outside_bounds": outside,
                                "residual_px": float(rms_after)})
            break
        chosen.append(k)
        values = [float(v) for v in fitted.extra]
        current = fitted
        steps.append({"component": COMPONENTS[k][0], "residual_px": float(rms_after), "delta_bic": step_bic})
    vector = np.zeros(12)
    for k, value in zip(chosen, values):
        vector[COMPONENTS[k][1]] = value * units[k]
    rss0, rss1, n = _rss(baseline, current)
    before, after = float(np.sqrt(rss0 / n)), float(np.sqrt(rss1 / n))
    entry = {"name": "calibration_error", "parameters": calibration_params(vector),
             "residual_before": before, "residual_after": after, "gain": gain(before, after),
             "evidence": {"domain": "phase", "unit": "projector px", "values": n, "parameters": len(chosen),
                          "delta_bic": delta_bic(rss0, rss1, n, len(chosen)),
                          "components": [COMPONENTS[k][0] for k in chosen], "steps": steps,
                          "implausible_step": implausible}}
    return entry, current
