"""The ``phase_filter`` candidate: spatially correlated phase noise, fitted from the residual's autocorrelation.

A phase file holds the phase after someone else's processing. White sensor noise decoded by Eq. (2) gives white
phase noise ``n``; the ``phase_filter`` effect smooths the wrapped phase as a unit phasor with a Gaussian ``g`` of
``sigma`` px. On fringes the phase is a ramp ``psi = k . u + n`` (``k`` the local phase gradient, rad/px): the
smoothed phasor is ``sum_u g(u) exp(i k . u) (1 + i n(u))``, so the noise leaves through the kernel
``h(u) = g(u) cos(k . u) / sum g cos(k . u)``: narrower across the fringes than along them. Its
autocorrelation at a lag ``d`` (continuous Gaussian) is
``exp(-|d|^2 / (4 sigma^2)) (cos(k . d) + exp(-|k|^2 sigma^2)) / (1 + exp(-|k|^2 sigma^2))``; without fringes
(``k = 0``) the familiar ``exp(-|d|^2 / (4 sigma^2))``. So, on the random part of the residual (measured - twin
after the best geometric model, less its quadratic, radial and periodic parts,
:func:`dptpu.sim.diagnosis.residuals.decompose_phase`; interior pixels only):

- (pixels within ``FILTER_MARGIN_PX`` of the measured region's border left out: a filter biases them)
- ``sigma_px``: the width whose predicted correlations (:func:`filter_correlations`: the discrete kernel of
  :func:`dptpu.sim.effects.camera.gaussian_blur`, modulated by each pixel's own phase gradient, averaged over the
  pixels weighted by their white-noise variance ``1 / b^2``) match the measured ones at the lags :data:`LAGS`
  (least squares, bounded search); a fit of ``exp(-|d|^2 / (4 sigma^2))`` alone reads the narrower kernel across
  the fringes as a narrower filter (0.76 px for 1.0 px on fringes ~8 px apart);
- the sensor's read noise that gives the residual through the filter: the white phase noise of a pixel is
  ``var(psi) = (2 / N) sigma_I^2 / b^2`` (least squares, Eq. (2); ``b`` the twin's modulation, DN), and the filter
  keeps ``sum h^2`` of it, so ``sigma_I^2 = rms^2 / mean(sum h^2 * 2 / (N b^2))`` with the RMS in radians.

The extended twin holds both: ``sensor_noise`` at that read noise (no shot noise) and ``phase_filter``.

Score. A correlated model predicts a pixel's residual from its neighbours; the white model of the twin does
not. ``residual_before`` is the random part's RMS, ``residual_after`` the RMS of what the best linear
prediction from the four neighbours leaves (the innovation); the gain and ``dBIC`` (2 parameters: sigma and
the level) follow :mod:`dptpu.sim.diagnosis.selection`. White noise leaves ``residual_after ~ residual_before``.
"""
from __future__ import annotations

import cv2
import numpy as np
from scipy.optimize import minimize_scalar

from dptpu.fpp.phase import wrapped_phase
from dptpu.sim.effects.camera import gaussian_blur
from dptpu.sim.image_formation import SequenceSpec

from .pixels import erode_mask
from .rerender import render_twin
from .residuals import decompose_phase
from .selection import delta_bic, gain

__all__ = ["fit_phase_filter", "fit_phase_filter_on_phase_file", "neighbour_correlations", "filter_noise_factor",
           "filter_correlations", "LAGS", "SIGMA_BOUNDS_PX"]

#: Pixels next to the measured region's border left out of the correlations (a filter's edge bias).
FILTER_MARGIN_PX = 6
#: Lags (rows, cols) whose correlations fit the filter width.
LAGS = ((0, 1), (1, 0), (1, 1), (0, 2), (2, 0))
#: Range of the fitted filter width (px): below 0.3 px the twin's kernel changes no pixel (a neighbour's weight
#: ``exp(-1 / (2 sigma^2))``), above 4 px the lags cannot tell widths apart.
SIGMA_BOUNDS_PX = (0.3, 4.0)
#: Pixels whose phase gradients stand for all in :func:`filter_correlations`.
SLOPE_SAMPLES = 400


def neighbour_correlations(image: np.ndarray, lags=LAGS) -> np.ndarray:
    """Correlation coefficients of ``image`` (H, W; NaN = not a value) with itself shifted by each lag."""
    out = []
    for dy, dx in lags:
        a = image[dy:, dx:]
        b = image[:image.shape[0] - dy, :image.shape[1] - dx]
        both = np.isfinite(a) & np.isfinite(b)
        out.append(float(np.corrcoef(a[both], b[both])[0, 1]) if both.sum() > 10 else float("nan"))
    return np.asarray(out)


def filter_noise_factor(sigma_px: float) -> float:
    """Standard deviation of white noise after :func:`~dptpu.sim.effects.camera.gaussian_blur` of ``sigma_px``,
    relative to before: ``sqrt(sum g^2)`` of its discrete kernel (``1 / (2 sqrt(pi) sigma)`` for a wide one)."""
    radius = max(int(np.ceil(4.0 * sigma_px)), 1) + 1
    delta = np.zeros((2 * radius + 1, 2 * radius + 1))
    delta[radius, radius] = 1.0
    return float(np.sqrt(np.sum(gaussian_blur(delta, sigma_px) ** 2)))


def _modulated_kernels(sigma_px: float, slopes: np.ndarray) -> np.ndarray:
    """The noise kernels ``h`` (P, n, n) of pixels with phase gradients ``slopes`` (P, 2: rad/px along rows and
    columns) through the phasor filter of ``sigma_px`` (module docstring), each normalized by its phasor mean."""
    radius = max(int(np.ceil(4.0 * sigma_px)), 1)  # gaussian_blur's kernel
    g1 = cv2.getGaussianKernel(2 * radius + 1, sigma_px)[:, 0]
    g = np.outer(g1, g1)
    v, u = np.mgrid[-radius:radius + 1, -radius:radius + 1]
    h = g[None] * np.cos(slopes[:, 0, None, None] * v[None] + slopes[:, 1, None, None] * u[None])
    return h / np.sum(h, axis=(1, 2), keepdims=True)


def _kernel_autocorrelation(h: np.ndarray, lag) -> np.ndarray:
    """``sum_u h(u) h(u + d)`` of each kernel (P, n, n) at ``lag`` ``d`` = (rows, cols), both >= 0."""
    dy, dx = lag
    n = h.shape[1]
    return np.sum(h[:, dy:, dx:] * h[:, :n - dy, :n - dx], axis=(1, 2))


def filter_correlations(sigma_px: float, slopes: np.ndarray, weights=None, lags=LAGS) -> np.ndarray:
    """Correlations at ``lags`` of white phase noise through the phase filter of ``sigma_px``, over pixels with
    phase gradients ``slopes`` (P, 2; rad/px along rows and columns) and white-noise variances ``weights``
    (P; default equal): ``sum_p w_p C_p(d) / sum_p w_p C_p(0)`` with ``C_p`` the autocorrelation of that pixel's
    noise kernel (module docstring)."""
    slopes = np.atleast_2d(np.asarray(slopes, dtype=np.float64))
    w = np.ones(len(slopes)) if weights is None else np.asarray(weights, dtype=np.float64)
    h = _modulated_kernels(sigma_px, slopes)
    zero = float(w @ _kernel_autocorrelation(h, (0, 0)))
    return np.array([float(w @ _kernel_autocorrelation(h, lag)) / zero for lag in lags])


def _sigma_from_correlations(rho: np.ndarray, slopes: np.ndarray, weights, lags=LAGS) -> float:
    """The filter width whose :func:`filter_correlations` match ``rho`` best (least squares over the finite
    lags); 0 when no lag is correlated (white noise)."""
    ok = np.isfinite(rho)
    if not ok.any() or np.max(rho[ok]) < 0.05:
        return 0.0
    chosen = [lag for lag, good in zip(lags, ok) if good]

    def misfit(sigma):
        return float(np.sum((filter_correlations(sigma, slopes, weights, chosen) - rho[ok]) ** 2))

    lo, hi = SIGMA_BOUNDS_PX
    grid = np.geomspace(lo, hi, 12)
    best = int(np.argmin([misfit(s) for s in grid]))
    left, right = grid[max(best - 1, 0)], grid[min(best + 1, len(grid) - 1)]
    solution = minimize_scalar(misfit, bounds=(left, right), method="bounded", options={"xatol": 1e-3})
    return float(solution.x)


def _slope_samples(projector_x: np.ndarray, interior: np.ndarray, to_rad: float, modulation_dn: np.ndarray):
    """Phase gradients (P, 2; rad/px) and modulations of up to ``SLOPE_SAMPLES`` interior pixels, evenly spread."""
    gy, gx = np.gradient(projector_x * to_rad)
    ok = interior & np.isfinite(gy) & np.isfinite(gx) & np.isfinite(modulation_dn) & (modulation_dn > 0)
    index = np.flatnonzero(ok)
    if index.size > SLOPE_SAMPLES:
        index = index[np.linspace(0, index.size - 1, SLOPE_SAMPLES).astype(int)]
    return np.column_stack([gy.ravel()[index], gx.ravel()[index]]), modulation_dn.ravel()[index]


def _innovation(image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Values with all four neighbours, and what the best linear prediction from their mean leaves."""
    centre = image[1:-1, 1:-1]
    neighbours = (image[:-2, 1:-1] + image[2:, 1:-1] + image[1:-1, :-2] + image[1:-1, 2:]) / 4.0
    ok = np.isfinite(centre) & np.isfinite(neighbours)
    y, x = centre[ok], neighbours[ok]
    slope = float(x @ y / (x @ x)) if x @ x > 0 else 0.0
    return y, y - slope * x


def fit_phase_filter(residual_px: np.ndarray, projector_x: np.ndarray, interior: np.ndarray, *, frequency: float,
                     extent: float, modulation_dn: np.ndarray, steps: int = 12) -> dict:
    """The ``phase_filter`` entry (module docstring).

    Parameters
    ----------
    residual_px : ndarray (H, W)
        Measured - twin projector coordinate after the best geometric model, projector px, NaN where unknown.
    projector_x : ndarray (H, W)
        Measured projector coordinate (for the periodic part and each pixel's phase gradient).
    interior : ndarray (H, W) bool
        Pixels to use (the edge band left out).
    frequency, extent : float
        Fringe frequency and projector extent along the fringe axis (px).
    modulation_dn : ndarray (H, W)
        The twin's modulation ``b`` of the phase's sequence (DN), for the read noise.
    steps : int
        Steps of that sequence.
    """
    residual = np.where(interior, residual_px, np.nan)
    random = decompose_phase(residual, projector_x, frequency=frequency, extent=extent)["maps"].get("random")
    if random is None:
        raise ValueError("phase_filter: fewer than 10 interior pixels with a residual")
    rho = neighbour_correlations(random)
    to_rad = 2.0 * np.pi * frequency / extent
    slopes, b = _slope_samples(projector_x, interior, to_rad, modulation_dn)
    white_variance = 2.0 / (steps * b * b) if b.size else np.ones(len(slopes))  # rad^2 per sigma_I^2
    sigma = _sigma_from_correlations(rho, slopes, white_variance) if len(slopes) else 0.0
    values, innovation = _innovation(random)
    n = int(values.size)
    rss0, rss1 = float(values @ values), float(innovation @ innovation)
    before, after = float(np.sqrt(rss0 / n)), float(np.sqrt(rss1 / n))
    random_rms = float(np.sqrt(np.nanmean(random ** 2)))
    kept = (_kernel_autocorrelation(_modulated_kernels(sigma, slopes), (0, 0)) if sigma > 0
            else np.ones(len(slopes)))  # the part of each pixel's white variance the filter keeps
    white_px = random_rms / np.sqrt(float(np.mean(kept))) if len(slopes) else random_rms
    read_noise = (float(random_rms * to_rad / np.sqrt(np.mean(kept * white_variance))) if b.size else 0.0)
    return {"name": "phase_filter", "parameters": {"sigma_px": sigma},
            "residual_before": before, "residual_after": after, "gain": gain(before, after),
            "extension": [{"sensor_noise": {"read_noise_dn": read_noise, "gain_dn_per_electron": 0.0,
                                            "dark_dn": 0.0}},
                          {"phase_filter": {"sigma_px": max(sigma, 1e-3)}}],
            "evidence": {"domain": "phase", "unit": "projector px", "values": n, "parameters": 2,
                         "delta_bic": delta_bic(rss0, rss1, n, 2),
                         "neighbour_correlations": {f"{dy},{dx}": float(r) for (dy, dx), r in zip(LAGS, rho)},
                         "random_rms_px": random_rms, "white_phase_noise_px": white_px,
                         "read_noise_dn": read_noise,
                         "score": "innovation: the residual less its best prediction from the four neighbours"}}


def fit_phase_filter_on_phase_file(measured, geometry, reference, material, bias=None) -> dict:
    """:func:`fit_phase_filter` on a phase file against the registration ``geometry`` (the best geometric model):
    the twin's modulation from a render of the file's sequence (``f x 12``, 8 bit) at that pose and rig.
    ``bias`` (H, W; projector px, optional): the twin's deterministic bias of the blurs named so far
    (:func:`dptpu.sim.diagnosis.blur_correction.blur_bias`), taken off the residual: a blur's smooth pattern
    near the silhouette is no correlated noise."""
    sequences = [SequenceSpec(measured.frequency, 12)]
    frames = render_twin(geometry.rig, reference, geometry.pose, material, sequences)[0]
    modulation = wrapped_phase(frames).modulation
    residual = measured.projector_x - geometry.model_x
    if bias is not None:
        residual = residual - bias
    # a filter biases the pixels within ~3 sigma of an edge (one-sided neighbours): deeper than the edge band
    interior = erode_mask(measured.valid, FILTER_MARGIN_PX) & geometry.mask & np.isfinite(residual)
    entry = fit_phase_filter(residual, measured.projector_x, interior, frequency=measured.frequency,
                             extent=measured.extent, modulation_dn=modulation, steps=12)
    if bias is not None:
        entry["evidence"]["less_the_bias_of_the_named_blurs"] = True
    return entry
