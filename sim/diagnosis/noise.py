"""The random part of the residual: the ``sensor_noise`` candidate in closed form.

After the best deterministic model, the per-value residual ``r`` (DN) of a pixel with model level ``M`` has
variance ``q^2 + read^2 + gain M`` (the twin's Poisson-Gaussian ``sensor_noise`` plus the quantization the twin
always applies, ``q^2 = 1/12`` DN^2). ``read^2`` and ``gain`` come from a least-squares line of ``r^2`` against
``M`` (both clipped at 0), corrected for the one gain per pixel fitted from its ``V`` values
(``E[r^2] = (V - 1) / V * variance``). The evidence is the Gaussian log-likelihood ratio of this variance model
against the twin's own ``q^2`` (deterministic renders: quantization only), as a BIC with 2 parameters.
"""
from __future__ import annotations

import numpy as np

from .selection import gain as gain_of

__all__ = ["QUANTIZATION_VAR_DN2", "fit_sensor_noise"]

#: Variance of rounding to integer DN (uniform on +-0.5).
QUANTIZATION_VAR_DN2 = 1.0 / 12.0


def fit_sensor_noise(residual: list, model: list) -> dict:
    """Fit ``read_noise_dn`` and ``gain_dn_per_electron`` to residuals and model levels (lists of (N, P))."""
    r2 = np.concatenate([r.ravel() ** 2 for r in residual])
    level = np.concatenate([m.ravel() for m in model])
    frames = sum(r.shape[0] for r in residual)
    r2 = r2 * frames / max(frames - 1, 1)
    A = np.column_stack([np.ones_like(level), level])
    (c0, c1), *_ = np.linalg.lstsq(A, r2, rcond=None)
    if c1 < 0:
        c0, c1 = float(r2.mean()), 0.0
    read2 = max(float(c0) - QUANTIZATION_VAR_DN2, 0.0)
    if c0 < QUANTIZATION_VAR_DN2:  # keep the mean variance: give the deficit back to the slope's intercept
        c1 = max(float(np.mean(r2) - QUANTIZATION_VAR_DN2) / max(float(level.mean()), 1e-9), 0.0)
    variance = QUANTIZATION_VAR_DN2 + read2 + c1 * np.clip(level, 0.0, None)
    n = r2.size
    q2 = QUANTIZATION_VAR_DN2
    loglik_ratio = 0.5 * float(np.sum(r2 / q2 - r2 / variance - np.log(variance / q2)))
    excess = max(float(np.mean(r2)) - QUANTIZATION_VAR_DN2, 0.0)
    # residual of the noise model: the random level the model leaves unexplained (DN), in 8 level bins
    edges = np.quantile(level, np.linspace(0.0, 1.0, 9))
    which = np.clip(np.searchsorted(edges, level, side="right") - 1, 0, 7)
    counts = np.bincount(which, minlength=8)
    measured_var = np.bincount(which, weights=r2, minlength=8) / np.maximum(counts, 1)
    model_var = np.bincount(which, weights=variance, minlength=8) / np.maximum(counts, 1)
    weights = counts / counts.sum()
    before = float(np.sqrt(np.sum(weights * np.abs(measured_var - QUANTIZATION_VAR_DN2))))
    after = float(np.sqrt(np.sum(weights * np.abs(measured_var - model_var))))
    return {"name": "sensor_noise",
            "parameters": {"read_noise_dn": float(np.sqrt(read2)), "gain_dn_per_electron": float(c1),
                           "dark_dn": 0.0},
            "residual_before": before, "residual_after": after, "gain": gain_of(before, after) if excess > 0 else 0.0,
            "evidence": {"domain": "noise", "unit": "DN (unexplained random level)", "values": int(n),
                         "parameters": 2, "delta_bic": float(2.0 * loglik_ratio - 2.0 * np.log(n)),
                         "excess_variance_dn2": excess}}
