"""The DP-TPU network: a small U-shaped vision transformer that refines a classical fringe order.

Inputs (Fig. 9a of the paper), per pixel: the high- and low-frequency wrapped phases and the coarse fringe
order of a classical two-frequency method (MF, Eq. (5); MW, Eq. (7); NT, Eq. (9)). Output: a continuous
fringe order of the high frequency, rounded in post-processing (:mod:`dptpu.models.inference`).

Input scaling (the network sees four channels, each of order 1):

- ``wrapped_high / (2*pi)`` and ``wrapped_low / (2*pi)``, in ``[0, 1)`` (the paper's normalization);
- ``coarse_order / frequency_high``, in ``[0, 1)`` for a right order (the fringe order divided by the
  number of periods across the projector: the normalized projector coordinate of the period's start),
  so one model serves every frequency;
- the coarse order's local consistency, ``clip(u - median3x3(u), -4, 4)`` with ``u = k_c + psi_h/2pi``
  (the coarse absolute phase in periods): about 0 where the order agrees with its neighbours and about
  ``n`` where it is off by ``n``. The second channel of the coarse order is our addition: through
  ``k_c / f_h`` alone an error of one order is a step of ``1/f_h`` (0.01 at ``f_h = 96``), too faint for a
  small network trained briefly on a CPU.

Architecture (``DPTPUConfig`` sets widths and depths):

- a full-resolution stem (3x3 convolution), kept for the output head;
- x4 downsampling (7x7 convolution, stride 4) into a four-stage Lite Vision Transformer encoder at
  strides 4/8/16/32: Convolutional Self-Attention (CSA) in stage 1, Recursive Atrous Self-Attention
  (RASA) in stages 2-4 (:mod:`dptpu.models.layers`);
- a U-MixFormer decoder: from the deepest stage to the shallowest, each stage's features are the
  queries of a cross attention whose keys and values come from the mix of all four stages (encoder
  features, replaced by decoder outputs once decoded) pooled to stride 32; the four decoded maps are
  upsampled to stride 4 and fused;
- x4 upsampling (pixel shuffle) back to full resolution, concatenated with the stem, two 3x3
  convolutions -> a correction ``delta``; the output is ``coarse_order + delta``. The last convolution
  starts at zero, so the untrained network returns the classical order, and training learns where and
  by how much it is wrong (residual form of the paper's continuous fringe-order output).

Any input size: the forward pass pads height and width to a multiple of 32 (edge replication) and crops
the output back.

Convention: images are ``(B, 1, H, W)`` float32, ``frequency_high`` is ``(B,)`` float32 (periods across
the projector); invalid pixels must carry finite values (the inference wrapper puts 0 there).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import torch
from torch import nn
from torch.nn import functional as F

from .layers import ChannelNorm, ConvSelfAttention, EncoderBlock, MixAttention, RecursiveAtrousSelfAttention

__all__ = ["DPTPUConfig", "DPTPUNet", "network_inputs", "median3x3", "PAD_MULTIPLE"]

TWO_PI = 2.0 * torch.pi
#: Height and width are padded to a multiple of this (the deepest stride).
PAD_MULTIPLE = 32


@dataclass(frozen=True)
class DPTPUConfig:
    """Widths and depths of :class:`DPTPUNet`.

    Attributes
    ----------
    widths : 4 ints
        Channels of encoder stages 1-4 (strides 4, 8, 16, 32); each a multiple of its ``heads``.
    depths : 4 ints
        Transformer blocks per stage.
    heads : 4 ints
        Attention heads per stage (the decoder uses ``heads[-1]``).
    decoder_width : int
        Channels of the U-MixFormer decoder; a multiple of ``heads[-1]``.
    stem_width : int
        Channels of the full-resolution stem and of the output head.
    reductions : 3 ints
        Key/value average-pooling factor of RASA in stages 2-4.
    recursions : int
        Recursions of RASA (shared weights).
    """

    widths: tuple[int, int, int, int] = (16, 32, 48, 64)
    depths: tuple[int, int, int, int] = (1, 1, 1, 1)
    heads: tuple[int, int, int, int] = (2, 2, 2, 4)
    decoder_width: int = 32
    stem_width: int = 8
    reductions: tuple[int, int, int] = (4, 2, 1)
    recursions: int = 2

    def to_dict(self) -> dict:
        return {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items()}

    @classmethod
    def from_dict(cls, values: dict) -> "DPTPUConfig":
        known = set(cls.__dataclass_fields__)
        unknown = set(values) - known
        if unknown:
            raise ValueError(f"unknown DP-TPU config keys {sorted(unknown)}; expected some of {sorted(known)}")
        return cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in values.items()})


def median3x3(x: torch.Tensor) -> torch.Tensor:
    """3x3 median of a ``(B, 1, H, W)`` map (edge replication); the 5th largest of 9, via TopK (exports)."""
    height, width = x.shape[-2], x.shape[-1]
    padded = F.pad(x, (1, 1, 1, 1), mode="replicate")
    stack = torch.cat([padded[:, :, dy:dy + height, dx:dx + width] for dy in range(3) for dx in range(3)], dim=1)
    return torch.topk(stack, 5, dim=1).values[:, 4:5]


def network_inputs(wrapped_high, wrapped_low, coarse_order, frequency_high) -> torch.Tensor:
    """The four scaled input channels, ``(B, 4, H, W)``.

    ``psi_h/2pi``, ``psi_l/2pi``, ``k_c/f_h`` and the local consistency of the coarse order,
    ``clip(u - median3x3(u), -4, 4)`` with ``u = k_c + psi_h/2pi`` the coarse absolute phase in periods
    (smooth where the order is right, so a pixel whose order is off by ``n`` stands out by about ``n``
    whatever the frequency).
    """
    scale = frequency_high.reshape(-1, 1, 1, 1)
    periods = coarse_order + wrapped_high / TWO_PI  # (B, 1, H, W)
    consistency = torch.clamp(periods - median3x3(periods), -4.0, 4.0)
    return torch.cat([wrapped_high / TWO_PI, wrapped_low / TWO_PI, coarse_order / scale, consistency], dim=1)


def pad_to_multiple(x: torch.Tensor, multiple: int = PAD_MULTIPLE) -> torch.Tensor:
    """Pad the last two axes of ``(B, C, H, W)`` at the bottom/right by edge replication to a multiple."""
    height, width = x.shape[-2], x.shape[-1]
    pad_h = (multiple - height % multiple) % multiple
    pad_w = (multiple - width % multiple) % multiple
    return F.pad(x, (0, pad_w, 0, pad_h), mode="replicate")


class DPTPUNet(nn.Module):
    """DP-TPU: LVT encoder + U-MixFormer decoder, residual on the classical fringe order.

    ``forward(wrapped_high, wrapped_low, coarse_order, frequency_high)`` with images ``(B, 1, H, W)``
    (radians in ``[0, 2pi)``, fringe orders) and ``frequency_high`` ``(B,)`` returns the continuous fringe
    order ``(B, 1, H, W)`` of the high frequency.
    """

    kind = "dptpu"

    def __init__(self, config: DPTPUConfig | None = None):
        super().__init__()
        config = config or DPTPUConfig()
        self.config = config
        w, d, h = config.widths, config.depths, config.heads
        self.stem = nn.Sequential(nn.Conv2d(4, config.stem_width, 3, padding=1), nn.GELU())
        self.embed = nn.ModuleList([
            nn.Sequential(nn.Conv2d(4, w[0], 7, stride=4, padding=3), ChannelNorm(w[0])),  # x4 down
            *[nn.Sequential(nn.Conv2d(w[i - 1], w[i], 3, stride=2, padding=1), ChannelNorm(w[i])) for i in (1, 2, 3)],
        ])
        stages = [nn.Sequential(*[EncoderBlock(w[0], ConvSelfAttention(w[0], h[0])) for _ in range(d[0])])]
        for i in (1, 2, 3):
            stages.append(nn.Sequential(*[
                EncoderBlock(w[i], RecursiveAtrousSelfAttention(w[i], h[i], config.reductions[i - 1],
                                                                config.recursions))
                for _ in range(d[i])]))
        self.stages = nn.ModuleList(stages)
        dw = config.decoder_width
        self.lateral = nn.ModuleList([nn.Conv2d(w[i], dw, 1) for i in range(4)])
        self.decoder = nn.ModuleList([MixAttention(dw, 4 * dw, h[-1]) for _ in range(4)])
        self.fuse = nn.Sequential(nn.Conv2d(4 * dw, dw, 1), nn.GELU())
        self.up = nn.Conv2d(dw, 16 * config.stem_width, 1)  # then pixel shuffle x4
        self.head = nn.Sequential(nn.Conv2d(2 * config.stem_width, config.stem_width, 3, padding=1), nn.GELU(),
                                  nn.Conv2d(config.stem_width, 1, 3, padding=1))
        nn.init.zeros_(self.head[-1].weight)
        nn.init.zeros_(self.head[-1].bias)

    def forward(self, wrapped_high, wrapped_low, coarse_order, frequency_high):
        height, width = wrapped_high.shape[-2], wrapped_high.shape[-1]
        x = pad_to_multiple(network_inputs(wrapped_high, wrapped_low, coarse_order, frequency_high))
        delta = self._correction(x)[:, :, :height, :width]
        return coarse_order + delta

    def _correction(self, x: torch.Tensor) -> torch.Tensor:
        stem = self.stem(x)  # (B, S, H, W)
        features = []
        for embed, stage in zip(self.embed, self.stages):
            x = stage(embed(x if not features else features[-1]))
            features.append(x)  # strides 4, 8, 16, 32
        maps = [lateral(f) for lateral, f in zip(self.lateral, features)]  # each (B, D, H/s, W/s)
        for i in (3, 2, 1, 0):  # U-MixFormer: deepest stage first
            mixed = torch.cat([F.avg_pool2d(m, 2 ** (3 - j)) if j < 3 else m for j, m in enumerate(maps)], dim=1)
            maps[i] = self.decoder[i](maps[i], mixed)
        fused = self.fuse(torch.cat(
            [maps[0]] + [F.interpolate(maps[i], scale_factor=2 ** i, mode="bilinear", align_corners=False)
                         for i in (1, 2, 3)], dim=1))  # (B, D, H/4, W/4)
        up = F.pixel_shuffle(self.up(fused), 4)  # (B, S, H, W), x4 up
        return self.head(torch.cat([up, stem], dim=1))  # (B, 1, H, W)
