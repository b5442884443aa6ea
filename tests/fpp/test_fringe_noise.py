"""Phase noise from each pixel's own N-step fit (dptpu.fpp.fringe_noise), and the pixels far noisier than the scan."""
import numpy as np
import pytest

from dptpu.fpp.fringe_noise import (
    DEFAULT_MAX_NOISE_RATIO,
    fit_residual,
    noise_outliers,
    phase_noise,
    quantization_phase_noise,
    sequence_phase_noise,
)
from dptpu.fpp.phase import wrapped_phase

TWO_PI = 2.0 * np.pi


def _frames(psi, steps, *, a=100.0, b=60.0, sigma=0.0, harmonic=0.0, seed=0):
    """``I_n = A + B cos(psi - 2 pi n / N) + harmonic cos(3 (psi - 2 pi n / N)) + noise`` (N, H, W) float64."""
    rng = np.random.default_rng(seed)
    delta = -TWO_PI * np.arange(steps)[:, None, None] / steps
    images = a + b * np.cos(psi + delta) + harmonic * np.cos(3 * (psi + delta))
    return images + rng.normal(0.0, sigma, images.shape) if sigma else images


def test_the_residual_is_what_the_fit_leaves_out():
    psi = np.linspace(0, TWO_PI, 200, endpoint=False).reshape(10, 20)
    images = _frames(psi, 12, harmonic=4.0)  # a third harmonic: orthogonal to the fit at 12 steps
    maps = wrapped_phase(images)
    assert fit_residual(images, maps.background, maps.modulation) == pytest.approx(np.full(psi.shape, 4.0 / np.sqrt(2)),
                                                                                    abs=1e-4)
    clean = _frames(psi, 12)
    maps = wrapped_phase(clean)
    assert fit_residual(clean, maps.background, maps.modulation).max() < 1e-4


@pytest.mark.parametrize("steps", [5, 12])
def test_the_measured_noise_is_the_phase_error_of_eq_2(steps):
    sigma, b = 2.0, 40.0
    psi = np.random.default_rng(1).uniform(0, TWO_PI, (200, 200))
    images = _frames(psi, steps, b=b, sigma=sigma, seed=steps)
    maps = wrapped_phase(images)
    noise = phase_noise(fit_residual(images, maps.background, maps.modulation), maps.modulation, steps)
    expected = np.sqrt(2.0 / steps) * sigma / b  # the least-squares phase's standard deviation
    error = np.angle(np.exp(1j * (maps.phase - psi)))
    assert np.sqrt(np.mean(noise ** 2)) == pytest.approx(expected, rel=0.03)  # its mean square is unbiased
    assert error.std() == pytest.approx(expected, rel=0.03)


def test_a_noisy_patch_is_an_outlier_and_a_clean_surface_loses_nothing():
    psi = np.random.default_rng(2).uniform(0, TWO_PI, (120, 160))
    for steps in (5, 12):
        images = _frames(psi, steps, sigma=1.0, seed=3)
        noisy = _frames(psi, steps, sigma=8.0 * DEFAULT_MAX_NOISE_RATIO / 5, seed=4)  # 8 times the noise
        images[:, 40:60, 50:80] = noisy[:, 40:60, 50:80]
        maps = wrapped_phase(images)
        noise = phase_noise(fit_residual(images, maps.background, maps.modulation), maps.modulation, steps)
        outliers = noise_outliers([noise], np.ones(psi.shape, bool))
        patch = np.zeros(psi.shape, bool)
        patch[40:60, 50:80] = True
        assert not outliers[~patch].any()
        # R^2 is sigma^2 chi^2_(N-3) / N: 8 times the noise reaches 5 times the median on P(chi^2_9 / 9 > 0.36) = 0.95
        # of the patch at 12 steps, P(chi^2_2 / 2 > 0.27) = 0.76 at 5 (the medians: 0.93 and 0.69 of their means)
        assert outliers[patch].mean() > (0.65 if steps == 5 else 0.9)
        assert not noise_outliers([noise], np.ones(psi.shape, bool), 0).any()  # 0: the test is off


def test_sequences_too_short_to_judge_and_bad_arguments():
    psi = np.zeros((4, 4))
    for steps in (3, 4):  # no residual, or one degree of freedom
        images = _frames(psi, steps, sigma=1.0)
        maps = wrapped_phase(images)
        assert phase_noise(fit_residual(images, maps.background, maps.modulation), maps.modulation, steps) is None
        # float images: no rounding floor either; 8-bit ones keep theirs (the unwrapping's quantization_noise)
        assert sequence_phase_noise(images, maps.background, maps.modulation) == (None, None)
        rounded = np.clip(np.rint(images), 0, 255).astype(np.uint8)
        noise, floor = sequence_phase_noise(rounded, maps.background, maps.modulation)
        assert noise is None and floor is not None and floor.shape == psi.shape
    assert not noise_outliers([None], np.ones((4, 4), bool)).any()
    with pytest.raises(ValueError, match="max_noise_ratio"):
        noise_outliers([], np.ones((4, 4), bool), 0.5)
    with pytest.raises(ValueError, match="N >= 3"):
        fit_residual(np.zeros((2, 4, 4)), psi, psi)


def _quantized(psi, steps, b, *, a=100.3, sigma=0.0, seed=5):
    """:func:`_frames` rounded to 8-bit digital numbers, as a camera delivers them."""
    return np.clip(np.rint(_frames(psi, steps, a=a, b=b, sigma=sigma, seed=seed)), 0, 255).astype(np.uint8)


@pytest.mark.parametrize("steps", [5, 12])
def test_rounding_alone_leaves_the_quantization_floor(steps):
    # a noiseless capture rounded to whole DN: the measured phase noise is sqrt(2 / N) / (sqrt(12) B), and so is the
    # phase error itself (rounding error uniform over one DN: variance 1/12)
    b = 15.0
    psi = np.random.default_rng(6).uniform(0, TWO_PI, (200, 200))
    images = _quantized(psi, steps, b, a=np.random.default_rng(7).uniform(90, 110, psi.shape))
    maps = wrapped_phase(images)
    noise, floor = sequence_phase_noise(images, maps.background, maps.modulation)  # as the unwrapping and phase node
    assert np.array_equal(noise, phase_noise(fit_residual(images, maps.background, maps.modulation), maps.modulation,
                                             steps))
    assert np.array_equal(floor, quantization_phase_noise(maps.modulation, steps, images.dtype))
    assert sequence_phase_noise(images, maps.background, maps.modulation, measure=False)[0] is None  # the test off
    expected = np.sqrt(2.0 / steps) / (np.sqrt(12.0) * b)
    assert np.sqrt(np.mean(floor ** 2)) == pytest.approx(expected, rel=0.01)
    assert np.sqrt(np.mean(noise ** 2)) == pytest.approx(expected, rel=0.05)
    # the rounding errors of the N images are not quite independent (one psi, fixed steps): within 10 %
    assert np.angle(np.exp(1j * (maps.phase - psi))).std() == pytest.approx(expected, rel=0.1)
    assert quantization_phase_noise(maps.modulation, steps, np.float32) is None  # float images are not rounded


def test_a_dim_surface_of_a_clean_capture_is_judged_against_its_own_quantization():
    # a clean 12-step capture (rounding only), modulation 48 DN but a dim patch of 6 DN: the patch's phase noise is 8x
    # the median from rounding alone (a phase as good as 6 DN allow): dropped against the median, kept with the floor;
    # a patch of the same modulation with 3 DN of camera noise is far above both and still goes
    steps = 12
    psi = np.random.default_rng(8).uniform(0, TWO_PI, (120, 160))
    b = np.full(psi.shape, 48.0)
    b[10:40, 20:60] = 6.0  # dim, clean
    images = _quantized(psi, steps, b)
    noisy = _quantized(psi, steps, 48.0, sigma=3.0, seed=9)
    images[:, 70:100, 90:130] = noisy[:, 70:100, 90:130]
    maps = wrapped_phase(images)
    noise = phase_noise(fit_residual(images, maps.background, maps.modulation), maps.modulation, steps)
    floor = quantization_phase_noise(maps.modulation, steps, images.dtype)
    valid = np.ones(psi.shape, bool)
    dim, noisy_patch = np.zeros(psi.shape, bool), np.zeros(psi.shape, bool)
    dim[10:40, 20:60], noisy_patch[70:100, 90:130] = True, True
    assert noise_outliers([noise], valid)[dim].mean() > 0.9  # the median alone drops the dim patch
    outliers = noise_outliers([noise], valid, DEFAULT_MAX_NOISE_RATIO, [floor])
    assert not outliers[dim].any()
    assert not outliers[~dim & ~noisy_patch].any()
    # 3 DN against 1/sqrt(12) DN of rounding: the noise is ~10x the median; below 5x on P(chi^2_9 / 9 < 0.25) ~ 2 %
    assert outliers[noisy_patch].mean() > 0.95
    with pytest.raises(ValueError, match="one entry per noise map"):
        noise_outliers([noise], valid, DEFAULT_MAX_NOISE_RATIO, [floor, floor])
