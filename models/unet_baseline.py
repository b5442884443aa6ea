"""Baseline without physics priors: a plain U-Net on the two wrapped phases only.

The comparison the paper draws (section "Unambiguous 3D reconstruction of static objects"): a network that
does not see the classical method's coarse fringe order has to infer the order from the wrapped phases
alone, and fails on frequencies it was not trained on.

Same call signature as :class:`dptpu.models.network.DPTPUNet` so that training, export and inference treat
both alike; ``coarse_order`` and ``frequency_high`` are accepted and ignored. Inputs ``psi_h/2pi`` and
``psi_l/2pi``; output ``ORDER_SCALE * head(features)``, a continuous fringe order (the fixed scale lets a
unit-size output reach the orders of ``f_h <= 96``).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import torch
from torch import nn
from torch.nn import functional as F

from .network import TWO_PI, pad_to_multiple

__all__ = ["UNetConfig", "UNetBaseline", "ORDER_SCALE"]

#: The network's raw output is multiplied by this many fringe orders.
ORDER_SCALE = 32.0


@dataclass(frozen=True)
class UNetConfig:
    """Channels of the four U-Net levels (strides 1, 2, 4, 8) and the bottleneck (stride 16)."""

    widths: tuple[int, int, int, int, int] = (8, 16, 32, 48, 64)

    def to_dict(self) -> dict:
        return {k: list(v) for k, v in asdict(self).items()}

    @classmethod
    def from_dict(cls, values: dict) -> UNetConfig:
        if set(values) - {"widths"}:
            raise ValueError(f"unknown U-Net config keys {sorted(set(values) - {'widths'})}; expected 'widths'")
        return cls(widths=tuple(values.get("widths", cls.widths)))


def _double_conv(c_in: int, c_out: int) -> nn.Sequential:
    return nn.Sequential(nn.Conv2d(c_in, c_out, 3, padding=1), nn.BatchNorm2d(c_out), nn.ReLU(),
                         nn.Conv2d(c_out, c_out, 3, padding=1), nn.BatchNorm2d(c_out), nn.ReLU())


class UNetBaseline(nn.Module):
    """Plain U-Net (Ronneberger et al. 2015): 4 downsamplings by max pooling, bilinear upsampling, skips."""

    kind = "unet"

    def __init__(self, config: UNetConfig | None = None):
        super().__init__()
        config = config or UNetConfig()
        self.config = config
        w = config.widths
        self.down = nn.ModuleList([_double_conv(2, w[0])] + [_double_conv(w[i - 1], w[i]) for i in range(1, 5)])
        self.up = nn.ModuleList([_double_conv(w[i + 1] + w[i], w[i]) for i in range(4)])
        self.out = nn.Conv2d(w[0], 1, 1)

    def forward(self, wrapped_high, wrapped_low, coarse_order, frequency_high):
        height, width = wrapped_high.shape[-2], wrapped_high.shape[-1]
        x = pad_to_multiple(torch.cat([wrapped_high / TWO_PI, wrapped_low / TWO_PI], dim=1))
        skips = []
        for i, block in enumerate(self.down):
            x = block(x if i == 0 else F.max_pool2d(x, 2))
            skips.append(x)
        x = skips.pop()
        for i in (3, 2, 1, 0):
            x = F.interpolate(x, scale_factor=2, mode="bilinear", align_corners=False)
            x = self.up[i](torch.cat([x, skips[i]], dim=1))
        return ORDER_SCALE * self.out(x)[:, :, :height, :width]
