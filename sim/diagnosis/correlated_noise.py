"""The ``phase_filter`` candidate: spatially correlated phase noise, fitted from the residual's autocorrelation.

A phase file holds the phase after someone else's processing. White sensor noise decoded by Eq. (2) gives white
phase noise; smoothed by a Gaussian of ``sigma`` px (the ``phase_filter`` effect, a unit-phasor smoothing) its
autocorrelation at a lag of ``d`` pixels is ``exp(-d^2 / (4 sigma^2))`` (the correlation of two Gaussians of
``sigma`` offset by ``d``). So, on the random part of the residual (measured - twin after the best geometric
model, less its quadratic, radial and periodic parts, :func:`dptpu.sim.diagnosis.residuals.decompose_phase`;
interior pixels only):

- (pixels within ``FILTER_MARGIN_PX`` of the measured region's border left out: a filter biases them)
- ``sigma_px`` from the correlations ``rho(d)`` at lags (1, 0), (0, 1), (1, 1), (2, 0), (0, 2): least squares of
  ``log rho(d) = -|d|^2 / (4 sigma^2)`` through the origin;
- the white phase noise before the filter: the random RMS divided by the filter's noise factor
  ``sqrt(sum g^2)`` (``g`` the discrete kernel of :func:`dptpu.sim.effects.camera.gaussian_blur`);
- the sensor's read noise that gives it through the twin's modulation ``b`` (DN) of each pixel:
  ``var(psi) = (2 / N) sigma_I^2 / b^2`` (least squares, Eq. (2)), so
  ``sigma_I = s_w / sqrt(mean(2 / (N b^2)))`` with ``s_w`` in radians.

The extended twin holds both: ``sensor_noise`` at that read noise (no shot noise) and ``phase_filter``.

Score. A correlated model predicts a pixel's residual from its neighbours; the white model of the twin does
not. ``residual_before`` is the random part's RMS, ``residual_after`` the RMS of what the best linear
prediction from the four neighbours leaves (the innovation); the gain and ``dBIC`` (2 parameters: sigma and
the level) follow :mod:`dptpu.sim.diagnosis.selection`. White noise leaves ``residual_after ~ residual_before``.
"""
from __future__ import annotations

import numpy as np

from dptpu.fpp.phase import wrapped_phase
from dptpu.sim.effects.camera import gaussian_blur
from dptpu.sim.image_formation import SequenceSpec

from .pixels import erode_mask
from .rerender import render_twin
from .residuals import decompose_phase
from .selection import delta_bic, gain

__all__ = ["fit_phase_filter", "fit_phase_filter_on_phase_file", "neighbour_correlations", "filter_noise_factor",
           "LAGS"]

#: Pixels next to the measured region's border left out of the correlations (a filter's edge bias).
FILTER_MARGIN_PX = 6
#: Lags (rows, cols) whose correlations fit the filter width.
LAGS = ((0, 1), (1, 0), (1, 1), (0, 2), (2, 0))


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


def _sigma_from_correlations(rho: np.ndarray, lags=LAGS) -> float:
    d2 = np.array([dy * dy + dx * dx for dy, dx in lags], dtype=np.float64)
    ok = np.isfinite(rho) & (rho > 0.01) & (rho < 1.0)
    if not ok.any():
        return 0.0
    slope = -float(np.sum(d2[ok] * np.log(rho[ok])) / np.sum(d2[ok] ** 2))  # 1 / (4 sigma^2)
    return float(0.5 / np.sqrt(slope)) if slope > 0 else 0.0


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
        Measured projector coordinate (for the periodic part).
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
    sigma = _sigma_from_correlations(rho)
    values, innovation = _innovation(random)
    n = int(values.size)
    rss0, rss1 = float(values @ values), float(innovation @ innovation)
    before, after = float(np.sqrt(rss0 / n)), float(np.sqrt(rss1 / n))
    random_rms = float(np.sqrt(np.nanmean(random ** 2)))
    white_px = random_rms / filter_noise_factor(sigma) if sigma > 0 else random_rms
    white_rad = white_px * 2.0 * np.pi * frequency / extent
    b = modulation_dn[interior & np.isfinite(modulation_dn) & (modulation_dn > 0)]
    read_noise = float(white_rad / np.sqrt(np.mean(2.0 / (steps * b * b)))) if b.size else 0.0
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


def fit_phase_filter_on_phase_file(measured, geometry, reference, material) -> dict:
    """:func:`fit_phase_filter` on a phase file against the registration ``geometry`` (the best geometric model):
    the twin's modulation from a render of the file's sequence (``f x 12``, 8 bit) at that pose and rig."""
    sequences = [SequenceSpec(measured.frequency, 12)]
    frames = render_twin(geometry.rig, reference, geometry.pose, material, sequences)[0]
    modulation = wrapped_phase(frames).modulation
    residual = measured.projector_x - geometry.model_x
    # a filter biases the pixels within ~3 sigma of an edge (one-sided neighbours): deeper than the edge band
    interior = erode_mask(measured.valid, FILTER_MARGIN_PX) & geometry.mask & np.isfinite(residual)
    return fit_phase_filter(residual, measured.projector_x, interior, frequency=measured.frequency,
                            extent=measured.extent, modulation_dn=modulation, steps=12)
