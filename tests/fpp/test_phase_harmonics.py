"""fpp.phase_harmonics: the N-step phase's error from a projector's harmonics, fitted against 12 steps and removed."""
import numpy as np
import pytest

from dptpu.fpp.phase import wrapped_phase
from dptpu.fpp.phase_harmonics import HarmonicPhaseError, fit_harmonic_phase_error, remove_harmonic_phase_error

PSI = np.linspace(0.0, 2 * np.pi, 3000, endpoint=False).reshape(50, 60)  # every phase of a period


def _frames(steps: int, second_harmonic: float, *, gamma: float | None = None) -> np.ndarray:
    """An N-step sequence of Eq. (1) (shift sign -1) through a projector with a second harmonic (or a gamma)."""
    shifts = -2 * np.pi * np.arange(steps) / steps
    if gamma is not None:  # a gamma projector: the pattern's level raised to gamma
        return np.stack([255 * (0.5 + 0.45 * np.cos(PSI + d)) ** gamma for d in shifts])
    return np.stack([100 + 60 * np.cos(PSI + d) + second_harmonic * 60 * np.cos(2 * (PSI + d)) for d in shifts])


@pytest.mark.parametrize("second_harmonic", [0.02, 0.08])
def test_a_second_harmonic_gives_three_steps_a_phase_error_at_three_times_the_phase(second_harmonic):
    psi3, psi12 = wrapped_phase(_frames(3, second_harmonic)).phase, wrapped_phase(_frames(12, second_harmonic)).phase
    assert np.abs(np.angle(np.exp(1j * (psi12 - PSI)))).max() < 1e-12  # 12 steps cancel the second harmonic
    error = fit_harmonic_phase_error([psi3], [psi12], [np.ones(PSI.shape, bool)], steps=3)
    assert error.amplitude_rad == pytest.approx(second_harmonic, rel=0.02)  # first order: B_2 / B_1
    before = np.abs(np.angle(np.exp(1j * (psi3 - PSI)))).max()
    after = np.abs(np.angle(np.exp(1j * (remove_harmonic_phase_error(psi3, error) - PSI)))).max()
    assert before == pytest.approx(second_harmonic, rel=0.05) and after < 0.1 * second_harmonic


@pytest.mark.parametrize("gamma", [1.6, 2.2])
def test_a_gamma_projector_calibrated_on_one_scene_corrects_another(gamma):
    """The error belongs to the projector, not the scene: fitted where the phase runs one way, removed where the
    fringes are shifted and a third darker (the levels scale, the harmonic's share does not)."""
    psi3 = wrapped_phase(_frames(3, 0.0, gamma=gamma)).phase
    psi12 = wrapped_phase(_frames(12, 0.0, gamma=gamma)).phase
    error = fit_harmonic_phase_error([psi3], [psi12], [np.ones(PSI.shape, bool)], steps=3)
    other = 0.66 * _frames(3, 0.0, gamma=gamma)[:, :, ::-1]  # another scene: other phases, another albedo
    other_truth = PSI[:, ::-1]
    measured = wrapped_phase(other).phase
    before = np.abs(np.angle(np.exp(1j * (measured - other_truth)))).max()
    after = np.abs(np.angle(np.exp(1j * (remove_harmonic_phase_error(measured, error) - other_truth)))).max()
    assert before > 0.05 and after < 0.3 * before  # the model is first order: a gamma of 2.2 leaves a quarter


def test_the_inversion_undoes_the_model_exactly():
    error = HarmonicPhaseError(steps=4, cos_rad=0.03, sin_rad=-0.05)
    measured = np.mod(PSI + error.at(PSI), 2 * np.pi)
    np.testing.assert_allclose(np.angle(np.exp(1j * (remove_harmonic_phase_error(measured, error) - PSI))), 0,
                               atol=1e-4)


def test_bad_input_is_refused():
    with pytest.raises(ValueError, match="steps must be >= 3"):
        fit_harmonic_phase_error([PSI], [PSI], [np.ones(PSI.shape, bool)], steps=2)
    with pytest.raises(ValueError, match="no valid pixel"):
        fit_harmonic_phase_error([PSI], [PSI], [np.zeros(PSI.shape, bool)], steps=3)
    with pytest.raises(ValueError, match="one shape"):
        fit_harmonic_phase_error([PSI], [PSI[:10]], [np.ones(PSI.shape, bool)], steps=3)
