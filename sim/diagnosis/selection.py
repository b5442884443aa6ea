"""Model selection: the Bayesian information criterion for nested least-squares models.

With Gaussian residuals of unknown variance, ``BIC = n log(RSS / n) + k log n`` (Schwarz 1978); a candidate
adding ``k`` parameters to the twin is preferred when ``dBIC = n log(RSS_0 / RSS) - k log n > 0``. We name an
effect only when ``dBIC > MIN_DELTA_BIC`` ("very strong" evidence on Kass & Raftery's scale, 1995) **and** it
removes at least ``MIN_GAIN`` of the residual RMS: with hundreds of thousands of values, a tiny systematic
correlation passes the BIC alone, and a cause must explain a visible part of what the twin gets wrong.
"""
from __future__ import annotations

import numpy as np

__all__ = ["MIN_DELTA_BIC", "MIN_GAIN", "delta_bic", "gain", "significant"]

MIN_DELTA_BIC = 10.0
MIN_GAIN = 0.05


def delta_bic(rss_before: float, rss_after: float, values: int, parameters: int) -> float:
    """``n log(RSS_0 / RSS) - k log n`` (positive: the candidate is preferred)."""
    rss_after = max(float(rss_after), 1e-300)
    return float(values * np.log(max(float(rss_before), 1e-300) / rss_after) - parameters * np.log(values))


def gain(rms_before: float, rms_after: float) -> float:
    """Fraction of the residual RMS removed: ``1 - rms_after / rms_before``."""
    return float(1.0 - rms_after / rms_before) if rms_before > 0 else 0.0


def significant(entry: dict) -> bool:
    """An effect entry (``evidence.delta_bic``, ``gain``) passes both criteria of the module docstring."""
    return entry["evidence"]["delta_bic"] > MIN_DELTA_BIC and entry["gain"] > MIN_GAIN
