"""Joint spatial-Fourier loss of the fringe order, Eqs. (15)-(17) of the paper, over valid pixels only.

``L = lambda1 * L_MSE + lambda2 * L_Fourier`` (Eq. (15)), ``lambda1 = 0.9``, ``lambda2 = 0.1`` (the paper's
weights); ``lambda2 = 0`` is the ablation without the Fourier term.

Invalid pixels. Let ``d = (k_pred - k_true) * valid`` be the error with the invalid pixels set to zero
(equivalently, the prediction replaced by the label there), so they contribute nothing to either term:

- ``L_MSE`` (Eq. (16)) = ``sum(d**2) / n_valid`` over the whole batch.
- ``L_Fourier`` (Eq. (17)) = the mean over samples of ``mean_bins |FFT2_ortho(d)| * sqrt(H*W / n_valid)``:
  the L1 norm of the difference of the two spectra (the FFT is linear, so
  ``FFT(k_pred) - FFT(k_true) = FFT(d)``), with the unitary ("ortho") FFT and a factor that makes the
  term independent of the share of valid pixels. By Parseval ``mean_bins |F|**2 * H*W / n_valid`` is the
  sample's MSE, so ``L_Fourier <= sqrt(L_MSE)`` of the sample, with equality when the error's spectrum
  is flat (a single wrong pixel). Samples without a valid pixel are left out of both terms.
"""
from __future__ import annotations

from dataclasses import dataclass

import torch

__all__ = ["LossTerms", "LossWeights", "fourier_term", "fringe_order_loss", "mse_term"]


@dataclass(frozen=True)
class LossWeights:
    """``lambda1`` (MSE) and ``lambda2`` (Fourier) of Eq. (15), and an optional Huber threshold.

    ``huber`` (fringe orders, None = the paper's plain MSE): the spatial term becomes the Huber loss
    ``2 * (|d| * huber - huber**2 / 2)`` for ``|d| > huber`` (equal to ``d**2`` below it, with a
    continuous slope), so pixels whose classical order is tens of orders off (NT where its key is
    ambiguous) cannot dominate the gradient. Not in the paper; see docs/network.md.
    """

    mse: float = 0.9
    fourier: float = 0.1
    huber: float | None = None

    def __post_init__(self):
        for name in ("mse", "fourier"):
            value = getattr(self, name)
            if not (value >= 0.0):  # also rejects NaN
                raise ValueError(f"loss weight {name} must be >= 0; got {value!r}")
        if self.huber is not None and not (self.huber > 0):
            raise ValueError(f"Huber threshold must be > 0 fringe orders; got {self.huber!r}")


@dataclass(frozen=True)
class LossTerms:
    """The weighted total (a differentiable scalar tensor) and its two terms (detached floats)."""

    total: torch.Tensor
    mse: float
    fourier: float


def _masked_error(pred: torch.Tensor, target: torch.Tensor, valid: torch.Tensor) -> torch.Tensor:
    if pred.shape != target.shape or pred.shape != valid.shape or pred.ndim != 4 or pred.shape[1] != 1:
        raise ValueError("pred, target and valid must all have shape (B, 1, H, W); got "
                         f"{tuple(pred.shape)}, {tuple(target.shape)}, {tuple(valid.shape)}")
    return (pred - target) * valid.to(pred.dtype)  # (B, 1, H, W), 0 at invalid pixels


def mse_term(pred: torch.Tensor, target: torch.Tensor, valid: torch.Tensor, huber: float | None = None
             ) -> torch.Tensor:
    """Eq. (16) over valid pixels: ``sum(d**2) / n_valid`` (fringe orders squared); 0 if none is valid.

    With ``huber``, ``d**2`` is replaced by ``2 * (huber * |d| - huber**2 / 2)`` where ``|d| > huber``.
    """
    d = _masked_error(pred, target, valid)
    n_valid = valid.sum()
    if huber is None:
        return (d * d).sum() / n_valid.clamp(min=1)
    size = d.abs()
    squared = torch.where(size <= huber, d * d, 2.0 * huber * size - huber * huber)
    return squared.sum() / n_valid.clamp(min=1)


def fourier_term(pred: torch.Tensor, target: torch.Tensor, valid: torch.Tensor) -> torch.Tensor:
    """Eq. (17) over valid pixels: mean over samples of ``mean |FFT2_ortho(d)| * sqrt(H*W / n_valid)``."""
    d = _masked_error(pred, target, valid)[:, 0]  # (B, H, W)
    spectrum = torch.fft.fft2(d, norm="ortho")  # (B, H, W) complex
    n_valid = valid.flatten(1).sum(dim=1).to(pred.dtype)  # (B,)
    hw = float(d.shape[-2] * d.shape[-1])
    per_sample = spectrum.abs().flatten(1).mean(dim=1) * torch.sqrt(hw / n_valid.clamp(min=1))  # (B,)
    has_valid = (n_valid > 0).to(pred.dtype)
    return (per_sample * has_valid).sum() / has_valid.sum().clamp(min=1)


def fringe_order_loss(pred: torch.Tensor, target: torch.Tensor, valid: torch.Tensor,
                      weights: LossWeights = LossWeights()) -> LossTerms:
    """Eq. (15): ``lambda1 * L_MSE + lambda2 * L_Fourier``.

    Parameters
    ----------
    pred : tensor (B, 1, H, W) float
        Continuous fringe order predicted by the network.
    target : tensor (B, 1, H, W) float
        Label fringe order (integers stored as float).
    valid : tensor (B, 1, H, W) bool
        Pixels that count.
    weights : LossWeights
        ``lambda1``, ``lambda2``; the Fourier term is not computed when ``lambda2 == 0``.

    Returns
    -------
    LossTerms
    """
    mse = mse_term(pred, target, valid, weights.huber)
    total = weights.mse * mse
    fourier_value = 0.0
    if weights.fourier > 0.0:
        fourier = fourier_term(pred, target, valid)
        total = total + weights.fourier * fourier
        fourier_value = float(fourier.detach())
    return LossTerms(total=total, mse=float(mse.detach()), fourier=fourier_value)
