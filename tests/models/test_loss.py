"""Joint spatial-Fourier loss (Eqs. 15-17) on inputs with known answers, invalid pixels excluded."""
import math

import pytest
import torch

from dptpu.models.loss import LossWeights, fourier_term, fringe_order_loss, mse_term


def _maps(h=8, w=16):
    target = torch.arange(h * w, dtype=torch.float32).reshape(1, 1, h, w) % 7
    return target, torch.ones(1, 1, h, w, dtype=torch.bool)


def test_mse_of_a_constant_error_is_its_square():
    target, valid = _maps()
    assert float(mse_term(target + 0.5, target, valid)) == pytest.approx(0.25)


def test_fourier_of_one_wrong_pixel_equals_the_root_mse():
    """A single error e: flat spectrum |F| = e/sqrt(HW) (unitary FFT), so L_F = e/sqrt(HW) = sqrt(MSE)."""
    target, valid = _maps()
    pred = target.clone()
    pred[0, 0, 3, 5] += 2.0
    hw = 8 * 16
    assert float(fourier_term(pred, target, valid)) == pytest.approx(2.0 / math.sqrt(hw), rel=1e-6)
    assert float(mse_term(pred, target, valid)) == pytest.approx(4.0 / hw, rel=1e-6)


def test_fourier_of_a_constant_error_is_its_dc_bin_only():
    """A constant error c: only the DC bin, c*sqrt(HW), so the mean over HW bins is c/sqrt(HW)."""
    target, valid = _maps()
    assert float(fourier_term(target + 3.0, target, valid)) == pytest.approx(3.0 / math.sqrt(128), rel=1e-6)


def test_invalid_pixels_do_not_count():
    target, valid = _maps()
    valid = valid.clone()
    valid[..., :, :8] = False  # left half invalid
    pred = target.clone()
    pred[..., :, :8] = 1e6  # garbage where invalid
    pred[0, 0, 2, 10] += 1.0  # one error where valid
    assert float(mse_term(pred, target, valid)) == pytest.approx(1.0 / 64, rel=1e-6)
    # one error among 64 valid pixels of a 128-pixel map: mean|F| = 1/sqrt(128), times sqrt(128/64)
    assert float(fourier_term(pred, target, valid)) == pytest.approx(1.0 / math.sqrt(64), rel=1e-6)


def test_total_is_the_weighted_sum_and_lambda2_zero_drops_the_fourier_term():
    target, valid = _maps()
    pred = target + 0.5
    terms = fringe_order_loss(pred, target, valid)
    assert float(terms.total) == pytest.approx(0.9 * 0.25 + 0.1 * 0.5 / math.sqrt(128), rel=1e-6)
    ablation = fringe_order_loss(pred, target, valid, LossWeights(mse=0.9, fourier=0.0))
    assert float(ablation.total) == pytest.approx(0.9 * 0.25) and ablation.fourier == 0.0


def test_sample_without_valid_pixels_is_left_out():
    target, valid = _maps()
    target2 = torch.cat([target, target])
    valid2 = torch.cat([valid, torch.zeros_like(valid)])
    pred = target2 + 0.5
    assert float(mse_term(pred, target2, valid2)) == pytest.approx(0.25)
    assert float(fourier_term(pred, target2, valid2)) == pytest.approx(0.5 / math.sqrt(128), rel=1e-6)


def test_gradient_flows_and_shape_errors_name_the_shapes():
    target, valid = _maps()
    pred = (target + 1.0).requires_grad_()
    fringe_order_loss(pred, target, valid).total.backward()
    assert pred.grad is not None and float(pred.grad.abs().sum()) > 0
    with pytest.raises(ValueError, match=r"\(B, 1, H, W\); got \(1, 1, 8, 16\), \(1, 1, 8, 8\)"):
        mse_term(target, target[..., :8], valid)
    with pytest.raises(ValueError, match="loss weight fourier must be >= 0"):
        LossWeights(fourier=-1.0)


def test_huber_variant_is_the_square_below_the_threshold_and_linear_above():
    """Errors 0.5 and 3 orders with threshold 1: 0.25 and 2*1*3 - 1 = 5, mean 2.625 (plain MSE: 4.625)."""
    target = torch.zeros(1, 1, 1, 2)
    pred = torch.tensor([[[[0.5, -3.0]]]])
    valid = torch.ones(1, 1, 1, 2, dtype=torch.bool)
    assert float(mse_term(pred, target, valid, huber=1.0)) == pytest.approx(2.625)
    assert float(mse_term(pred, target, valid)) == pytest.approx(4.625)
    terms = fringe_order_loss(pred, target, valid, LossWeights(mse=1.0, fourier=0.0, huber=1.0))
    assert terms.mse == pytest.approx(2.625)
    with pytest.raises(ValueError, match="Huber threshold must be > 0 fringe orders; got 0"):
        LossWeights(huber=0)
