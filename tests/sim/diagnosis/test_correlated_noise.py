"""The phase_filter candidate: its width from the residual's autocorrelation, its read noise from the twin's
modulation, and white noise not taken for a filter."""
import numpy as np
import pytest

from dptpu.sim.diagnosis.correlated_noise import filter_noise_factor, fit_phase_filter, neighbour_correlations
from dptpu.sim.diagnosis.pixels import erode_mask
from dptpu.sim.effects.phase import phase_filter

FREQUENCY, EXTENT = 96.0, 912.0
TO_PX = EXTENT / (2 * np.pi * FREQUENCY)


def _filtered_noise(sigma_px, noise_rad, seed=0, shape=(120, 160), slope=0.3):
    """A wrapped phase ramp (``slope`` rad/px along x, as fringes are) with white noise, through the phase
    filter; returns the residual (projector px) and the projector coordinate, inside a disk."""
    rng = np.random.default_rng(seed)
    v, u = np.mgrid[0:shape[0], 0:shape[1]]
    ramp = slope * u
    disk = (u - shape[1] / 2) ** 2 + (v - shape[0] / 2) ** 2 < (0.45 * shape[0]) ** 2
    noisy = np.where(disk, np.mod(ramp + noise_rad * rng.normal(size=shape), 2 * np.pi), np.nan)
    smoothed = phase_filter(noisy, sigma_px, disk) if sigma_px > 0 else noisy
    residual = np.angle(np.exp(1j * (smoothed - ramp))) * TO_PX
    return residual, ramp * TO_PX, disk


def test_filter_noise_factor_matches_the_wide_gaussian_limit():
    assert filter_noise_factor(3.0) == pytest.approx(1 / (2 * np.sqrt(np.pi) * 3.0), rel=0.02)


def test_correlations_of_a_gaussian_filter_follow_exp_minus_d2_over_4_sigma2():
    residual, _, _ = _filtered_noise(1.5, 0.05, slope=0.0)
    rho = neighbour_correlations(residual[20:-20, 30:-30], lags=((1, 0), (2, 0)))
    np.testing.assert_allclose(rho, np.exp(-np.array([1.0, 4.0]) / (4 * 1.5 ** 2)), atol=0.03)


@pytest.mark.parametrize("sigma", [1.0, 1.5])
def test_hidden_phase_filter_width_and_read_noise_within_20_percent(sigma):
    noise_rad = 0.05
    residual, x, disk = _filtered_noise(sigma, noise_rad, seed=int(10 * sigma))
    interior = erode_mask(disk, 6)
    modulation = np.full(disk.shape, 60.0)
    entry = fit_phase_filter(residual, x, interior, frequency=FREQUENCY, extent=EXTENT, modulation_dn=modulation)
    assert entry["parameters"]["sigma_px"] == pytest.approx(sigma, rel=0.2)
    assert entry["gain"] > 0.3 and entry["evidence"]["delta_bic"] > 100
    # the read noise that gives the white phase noise: sigma_I = s / sqrt(2 / (N b^2)), N = 12, b = 60 DN
    assert entry["evidence"]["read_noise_dn"] == pytest.approx(noise_rad * 60.0 / np.sqrt(2 / 12), rel=0.2)
    assert {next(iter(e)) for e in entry["extension"]} == {"sensor_noise", "phase_filter"}


def test_white_phase_noise_is_not_a_filter():
    residual, x, disk = _filtered_noise(0.0, 0.05, seed=3)
    entry = fit_phase_filter(residual, x, disk, frequency=FREQUENCY, extent=EXTENT,
                             modulation_dn=np.full(disk.shape, 60.0))
    assert entry["gain"] < 0.05  # below the naming threshold (selection.MIN_GAIN)
