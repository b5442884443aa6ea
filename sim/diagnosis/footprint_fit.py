"""The ``pixel_footprint`` candidate, fitted on the edge band: the pixels next to the border of the measured region.

The baseline twin samples each pixel at its centre: a silhouette is sharp, and the pixels next to it hold the
surface's own phase. A real pixel integrates over its area and the lens' blur
(:mod:`dptpu.sim.effects.footprint`): next to a silhouette it mixes the surface with what lies beyond, and its
phase is pulled towards its neighbours' (at grazing incidence the phase changes fast across a pixel). So the edge
band (``EDGE_BAND_PX`` px, left out of every other fit) is where the effect shows, on raw frames and on a phase
file alike.

The fit: the registered reference (the best geometric model's rig and pose) rendered with
``pixel_footprint`` (``samples`` 4, ``blur_sigma_px`` on a grid, then a bounded Brent search) and decoded like
the data; least squares on the measured - twin projector coordinate over the measured edge band (compared modulo
a fringe period: the orders are the measurement's business; an edge pixel the twin does not decode keeps the
baseline's residual). The alternatives are fitted on the same pixels: ``camera_defocus`` (the frames blurred
after the pixel sampling) and, on a phase file with correlated noise, the ``phase_filter`` of the correlations
(a filter pulls an edge pixel towards its one-sided neighbours too). ``pixel_footprint`` is named only when it
explains the edge band better than each by ``MIN_DELTA_BIC`` (one parameter each, so this is the likelihood
ratio); the evidence says by how much.
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import minimize_scalar

from dptpu.sim.image_formation import SequenceSpec

from .pixels import erode_mask
from .rerender import decode, render_twin
from .selection import MIN_DELTA_BIC, delta_bic, gain

__all__ = ["fit_pixel_footprint", "edge_defocus_entry", "FOOTPRINT_SAMPLES", "FOOTPRINT_GRID_PX", "EDGE_OVER_INTERIOR",
           "edge_band"]

#: Rays per pixel and axis of the fitted footprint.
FOOTPRINT_SAMPLES = 4
#: Grid of the blur's sigma (camera px) before the bounded search.
FOOTPRINT_GRID_PX = (0.0, 0.7, 1.4, 2.5)
_DEFOCUS_GRID_PX = (0.3, 0.8, 1.5, 2.5)
#: The fit runs only when the baseline's edge band RMS exceeds this many times the interior's (the registration
#: RMS): a twin-like edge band holds nothing to fit, and the renders at 16 rays per pixel are the costly part.
EDGE_OVER_INTERIOR = 2.0


def edge_band(valid: np.ndarray, width_px: int) -> np.ndarray:
    """The pixels of ``valid`` (H, W) within ``width_px`` of its border."""
    return valid & ~erode_mask(valid, width_px)


def _search(objective, grid) -> tuple[float, float]:
    values = [objective(v) for v in grid]
    best = int(np.argmin(values))
    value, rss = float(grid[best]), float(values[best])
    left, right = grid[max(best - 1, 0)], grid[min(best + 1, len(grid) - 1)]
    if right > left:
        solution = minimize_scalar(objective, bounds=(left, right), method="bounded", options={"xatol": 0.02})
        if solution.fun < rss:
            value, rss = float(solution.x), float(solution.fun)
    return value, rss


def twin_sequences(measured) -> tuple[list, dict]:
    """The sequences the twin renders for ``measured`` (its own; a phase file: the paper's ``f x 12`` and
    ``1 x 12``) and the render's keyword arguments (the frames' bit depth and pattern)."""
    if measured.has_frames:
        return list(measured.sequences), {"bit_depth": measured.bit_depth, "pattern": measured.pattern}
    return [SequenceSpec(measured.frequency, 12), SequenceSpec(1.0, 12)], {}


def fit_pixel_footprint(measured, geometry, reference, material, *, edge_px: int = 2,
                        phase_filter_sigma: float | None = None) -> dict:
    """The ``pixel_footprint`` entry (module docstring) against the registration ``geometry``.

    Frames are rendered with the data's sequences (a phase file: the paper's ``f x 12`` and ``1 x 12``).
    """
    sequences, kwargs = twin_sequences(measured)
    to_x = measured.extent / (2.0 * np.pi * measured.frequency)
    period = measured.extent / measured.frequency
    edge = edge_band(measured.valid, edge_px)
    target = measured.projector_x[edge]

    def residual(effects) -> np.ndarray:
        frames = render_twin(geometry.rig, reference, geometry.pose, material, sequences, effects=effects, **kwargs)
        x = decode(frames, sequences, bit_depth=kwargs.get("bit_depth", 8), effects=effects)[edge] * to_x
        return np.mod(target - x + 0.5 * period, period) - 0.5 * period

    baseline = residual([])
    known = np.isfinite(baseline)
    baseline = baseline[known]
    n = int(known.sum())
    edge_rms = float(np.sqrt(np.mean(baseline ** 2))) if n else 0.0
    if n < 10 or edge_rms <= EDGE_OVER_INTERIOR * geometry.rms_px:
        return {"name": "pixel_footprint", "parameters": {}, "residual_before": edge_rms, "residual_after": edge_rms,
                "gain": 0.0, "evidence": {"domain": "phase", "unit": "projector px", "values": n, "parameters": 1,
                                          "delta_bic": 0.0, "pixels": f"edge band {edge_px} px",
                                          "not_fitted": f"the edge band ({edge_rms:.4g} px RMS) is within "
                                                        f"{EDGE_OVER_INTERIOR:g}x the interior's "
                                                        f"({geometry.rms_px:.4g} px)"}}

    def rss(effects) -> float:
        r = residual(effects)[known]
        r = np.where(np.isfinite(r), r, baseline)
        return float(r @ r)

    rss0 = float(baseline @ baseline)
    sigma, rss1 = _search(lambda s: rss([{"pixel_footprint": {"samples": FOOTPRINT_SAMPLES,
                                                               "blur_sigma_px": float(s)}}]),
                          np.asarray(FOOTPRINT_GRID_PX))
    defocus, rss_defocus = _search(lambda s: rss([{"camera_defocus": {"sigma_px": float(s)}}]),
                                   np.asarray(_DEFOCUS_GRID_PX))
    over_defocus = float(n * np.log(max(rss_defocus, 1e-300) / max(rss1, 1e-300))) if n else 0.0
    alternatives = {"camera_defocus": {"sigma_px": defocus, "residual_after": float(np.sqrt(rss_defocus / n)),
                                       "delta_bic_over_it": over_defocus}}
    if phase_filter_sigma:  # a phase file's own filter biases the edge band too (one-sided neighbours)
        rss_filter = rss([{"phase_filter": {"sigma_px": float(phase_filter_sigma)}}])
        alternatives["phase_filter"] = {"sigma_px": float(phase_filter_sigma),
                                        "residual_after": float(np.sqrt(rss_filter / n)),
                                        "delta_bic_over_it": float(n * np.log(max(rss_filter, 1e-300) /
                                                                              max(rss1, 1e-300)))}
    before, after = (float(np.sqrt(rss0 / n)), float(np.sqrt(rss1 / n))) if n else (0.0, 0.0)
    return {"name": "pixel_footprint", "parameters": {"samples": FOOTPRINT_SAMPLES, "blur_sigma_px": sigma},
            "residual_before": before, "residual_after": after, "gain": gain(before, after),
            "evidence": {"domain": "phase", "unit": "projector px", "values": n, "parameters": 1,
                         "delta_bic": delta_bic(rss0, rss1, n, 1) if n else 0.0, "pixels": f"edge band {edge_px} px",
                         "alternatives": alternatives, "edge_rss": {"baseline": rss0, "pixel_footprint": rss1},
                         "beats_alternatives": all(a["delta_bic_over_it"] > MIN_DELTA_BIC
                                                   for a in alternatives.values())}}


def edge_defocus_entry(footprint: dict) -> dict | None:
    """On a phase file, the ``camera_defocus`` of the edge band as its own entry (from the footprint entry's
    alternative): named when it explains the edge band better than ``pixel_footprint`` and than the phase
    filter (the frames blurred after the pixel sampling; on a smooth surface it leaves a 12-step phase
    unchanged, so the edge band is all a phase file shows of it). None when the footprint was not fitted."""
    evidence = footprint["evidence"]
    alternative = evidence.get("alternatives", {}).get("camera_defocus")
    if alternative is None:
        return None
    n = evidence["values"]
    before, after = footprint["residual_before"], alternative["residual_after"]
    others = [-alternative["delta_bic_over_it"]]
    if "phase_filter" in evidence["alternatives"]:
        filtered = evidence["alternatives"]["phase_filter"]["residual_after"]
        others.append(float(n * np.log(max(filtered, 1e-300) ** 2 / max(after, 1e-300) ** 2)))
    return {"name": "camera_defocus", "parameters": {"sigma_px": alternative["sigma_px"]},
            "residual_before": before, "residual_after": after, "gain": gain(before, after),
            "evidence": {"domain": "phase", "unit": "projector px", "values": n, "parameters": 1,
                         "delta_bic": delta_bic(n * before ** 2, n * after ** 2, n, 1),
                         "pixels": evidence["pixels"], "delta_bic_over_footprint_and_filter": others,
                         "beats_alternatives": all(o > MIN_DELTA_BIC for o in others)}}
