"""Photometric candidates judged on the phase alone (a phase file: no frames to fit).

The twin renders the registered reference with the effect on (the paper's ``f x 12`` and ``1 x 12`` sequences,
8 bit, :func:`dptpu.sim.diagnosis.rerender.render_twin`), decodes it like the data, and the effect's main
parameter is fitted to the measured projector coordinate on the registration's pixels (grid, then bounded
Brent). Only effects that move the decoded phase of a 12-step sequence can be seen this way: the step-scale
error and the drift (a ripple at 2x and 1x the fringe frequency). Gamma below the 11th harmonic, ambient light,
defocus and saturation below clipping leave a 12-step phase unchanged, so a phase file cannot show them.
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import minimize_scalar

from dptpu.sim.image_formation import SequenceSpec

from .candidates import Candidate
from .rerender import decode, render_twin
from .selection import delta_bic, gain

__all__ = ["PHASE_VISIBLE", "fit_phase_candidate"]

#: Photometric effects a 12-step phase shows (module docstring).
PHASE_VISIBLE = (
    Candidate("intensity_drift", "rate_per_frame", (-0.02, 0.02), 0.0, {"sigma": 0.0}),
    Candidate("phase_shift_error", "scale", (0.95, 1.05), 1.0, {"sigma_rad": 0.0}),
)


def fit_phase_candidate(measured, rig, reference, material, registration, candidate: Candidate) -> dict:
    """Fit ``candidate`` on the phase residual (projector px) over ``registration.mask``."""
    neutral = candidate.neutral
    if neutral is None:
        raise ValueError(f"{candidate.name}: a phase-only fit needs the parameter value at which the effect does "
                         f"nothing (Candidate.neutral)")
    sequences = [SequenceSpec(measured.frequency, 12), SequenceSpec(1.0, 12)]
    to_x = measured.extent / (2.0 * np.pi * measured.frequency)
    mask = registration.mask & np.isfinite(measured.projector_x)
    target = measured.projector_x[mask]
    period = measured.extent / measured.frequency

    def residual(value):
        effects = [candidate.effect(value)] if value != neutral else []
        frames = render_twin(rig, reference, registration.pose, material, sequences, effects=effects)
        x = decode(frames, sequences) * to_x
        r = x[mask] - target
        r = np.mod(r + 0.5 * period, period) - 0.5 * period  # orders are the measurement's business
        return np.where(np.isfinite(r), r, 0.0)

    def rss(value):
        r = residual(value)
        return float(np.sum(r * r))

    lo, hi = candidate.bounds
    grid = np.unique(np.append(np.linspace(lo, hi, 7), neutral))
    values = [rss(v) for v in grid]
    best = int(np.argmin(values))
    value, best_rss = float(grid[best]), float(values[best])
    left, right = grid[max(best - 1, 0)], grid[min(best + 1, len(grid) - 1)]
    solution = minimize_scalar(rss, bounds=(left, right), method="bounded", options={"xatol": 1e-4 * (hi - lo)})
    if solution.fun < best_rss:
        value, best_rss = float(solution.x), float(solution.fun)
    rss0 = rss(neutral)
    n = int(mask.sum())
    before, after = float(np.sqrt(rss0 / n)), float(np.sqrt(best_rss / n))
    return {"name": candidate.name, "parameters": {candidate.main: value, **candidate.fixed},
            "residual_before": before, "residual_after": after, "gain": gain(before, after),
            "evidence": {"domain": "phase", "unit": "projector px", "values": n, "parameters": 1,
                         "delta_bic": delta_bic(rss0, best_rss, n, 1), "rendered": [s.label for s in sequences]}}
