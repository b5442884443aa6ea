"""The DP-TPU network: a small U-shaped vision transformer that refines a classical fringe order.

Inputs (Fig. 9a of the paper), per pixel: the high- and low-frequency wrapped phases ``psi_h``, ``psi_l``
(radians) and the coarse fringe order ``k_c`` of a classical two-frequency method (MF, Eq. (5); MW,
Eq. (7); NT, Eq. (9)). Output: a continuous fringe order of the high frequency, rounded in
post-processing (:mod:`dptpu.models.inference`).

Architecture 2 (``DPTPUConfig.architecture``), built for speed: nothing but elementwise operations at
full resolution; every convolution and attention works at stride 4 or coarser.

1. **Full-resolution inputs** (elementwise): ``sin psi_h, cos psi_h, sin psi_l, cos psi_l`` (smooth under
   a strided convolution, unlike ``psi / 2pi`` with its wraps) and the deviation ``r - u_c`` of the
   coarse absolute phase in periods ``u_c = k_c + psi_h / 2pi`` from a smooth robust reference ``r``
   (below), clipped to +-4 periods: an order off by ``n`` stands out by ``n`` whatever the frequency.
2. **x4 down**: a 4x4 stride-4 patch embedding (convolution) of those five maps, plus two stride-4 maps:
   the patch median ``m`` of ``u_c`` scaled by ``1 / f_h`` (``[0, 1)`` for a right order: one model
   serves every frequency), and ``m`` minus the median of its 3x3 neighbourhood of patch medians (a whole
   patch off). ``m`` is the median of 9 of the patch's 16 pixels (rows and columns 0, 2, 3) by a min/max
   sorting network (cheap elementwise ops at stride 4), invalid pixels (``u_c = 0``) standing in as
   ``+-FILL`` alternately; patches with fewer than 5 valid samples get weight 0. ``r`` is the bilinear
   x4 upsampling of the weighted medians divided by that of the weights (normalized convolution): a
   smooth estimate of ``u`` that isolated wrong orders and mask borders do not move.
3. **Encoder** (Lite Vision Transformer) at strides 4/8/16/32: Convolutional Self-Attention (CSA) in
   stage 1, Recursive Atrous Self-Attention (RASA) in stages 2-4 (:mod:`dptpu.models.layers`).
4. **Decoder** (U-MixFormer): deepest stage first, each stage's features are the queries of a cross
   attention whose keys and values are the mix of all four stages pooled to stride
   ``32 * decoder_pool`` (decoded stages replace their encoder maps); the four maps are upsampled to
   stride 4 and summed.
5. **x4 up** (depth-to-space): two 1x1 convolutions to 16 channels each, pixel-shuffled to two full-resolution
   maps ``a`` and ``g`` (each pixel of a patch has its own channel, so an edge can fall anywhere in it).
   The prediction is the absolute phase in periods::

       u = u_c + a + g * (r - u_c)

   a per-pixel blend between the classical ``u_c`` and the reference ``r`` (``g = 1``: the pixel takes
   the phase of its neighbourhood, which fixes an isolated wrong order), plus a learned correction ``a``.
   The continuous fringe order is ``u - psi_h/2pi = k_c + a + g (r - u_c)``; rounding it decides the
   order against the pixel's own ``psi_h``, so a ``u`` within half a period of the truth gives every
   pixel its right order, noisy or not.

The last two 1x1 convolutions start at zero (``a = g = 0``), so the untrained network returns the classical
order exactly; training learns where and by how much it is wrong (residual form of the paper's
continuous fringe-order output). ``g`` is that layer's output times ``GATE_GAIN`` so that AdamW reaches
``g = 1`` in tens of steps.

Any input size: the forward pass pads height and width to a multiple of 32 (edge replication) and crops
the output back.

Convention: images are ``(B, 1, H, W)`` float32, ``frequency_high`` is ``(B,)`` float32 (periods across
the projector); invalid pixels must carry 0 in all three images (the inference wrapper and
:func:`dptpu.fpp.dataset.read_sample` do that).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import torch
from torch import nn
from torch.nn import functional as F

from .layers import (
    ChannelNorm,
    ConvSelfAttention,
    EncoderBlock,
    MixAttention,
    RecursiveAtrousSelfAttention,
)

__all__ = [
    "ARCHITECTURE",
    "GATE_GAIN",
    "PAD_MULTIPLE",
    "PATCH",
    "TWO_PI",
    "DPTPUConfig",
    "DPTPUNet",
    "median3x3",
    "median9",
    "network_features",
    "pad_to_multiple",
    "patch_median",
]

TWO_PI = 2.0 * torch.pi
#: Height and width are padded to a multiple of this (the deepest stride).
PAD_MULTIPLE = 32
#: Side of the patches of the x4 down / x4 up steps, pixels.
PATCH = 4
#: The blend map ``g`` is the last layer's output times this (AdamW moves a weight by about the
#: learning rate per step, so ``g`` can reach 1 in ~1 / (GATE_GAIN * lr) steps).
GATE_GAIN = 16.0
#: Consistency features are clipped to +- this many periods.
CONSISTENCY_CLIP = 4.0
#: Version of the architecture; configs and checkpoints of another version do not load.
ARCHITECTURE = 2
#: Full-resolution input maps of the patch embedding (sin/cos of both phases, clipped r - u_c).
FULL_RES_CHANNELS = 5
#: Stride-4 input maps (patch median of u_c / f_h, its deviation from the neighbouring patches).
PATCH_CHANNELS = 2
#: Rows and columns of a 4x4 patch whose 9 pixels give the patch median.
MEDIAN_OFFSETS = (0, 2, 3)
#: Value (periods) that stands in for an invalid pixel in the patch median, with alternating sign.
FILL = 1.0e4


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
    reductions : 3 ints
        Key/value average-pooling factor of RASA in stages 2-4.
    recursions : int
        Recursions of RASA (shared weights).
    decoder_pool : int
        The decoder's keys and values are the mixed map pooled to stride ``32 * decoder_pool``.
    mlp_ratio : int
        Hidden channels of every Mix-FFN, as a multiple of its input channels.
    architecture : int
        Must be :data:`ARCHITECTURE` (2); architecture 1 (a full-resolution stem and head, ``stem_width``)
        is gone.
    """

    widths: tuple[int, int, int, int] = (8, 16, 24, 32)
    depths: tuple[int, int, int, int] = (1, 1, 1, 1)
    heads: tuple[int, int, int, int] = (1, 1, 1, 1)
    decoder_width: int = 8
    reductions: tuple[int, int, int] = (8, 4, 2)
    recursions: int = 2
    decoder_pool: int = 2
    mlp_ratio: int = 2
    architecture: int = ARCHITECTURE

    def __post_init__(self):
        if self.architecture != ARCHITECTURE:
            raise ValueError(f"DP-TPU config architecture {self.architecture}: this version builds architecture "
                             f"{ARCHITECTURE} only; retrain the model (dptpu train)")
        for name, count in (("widths", 4), ("depths", 4), ("heads", 4), ("reductions", 3)):
            value = getattr(self, name)
            if len(value) != count or any(int(v) < 1 for v in value):
                raise ValueError(f"DP-TPU config {name} must be {count} integers >= 1; got {list(value)}")
        for name in ("decoder_width", "recursions", "decoder_pool", "mlp_ratio"):
            if int(getattr(self, name)) < 1:
                raise ValueError(f"DP-TPU config {name} must be an integer >= 1; got {getattr(self, name)!r}")

    def to_dict(self) -> dict:
        return {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items()}

    @classmethod
    def from_dict(cls, values: dict) -> DPTPUConfig:
        values = dict(values)
        if "stem_width" in values and "architecture" not in values:
            raise ValueError("DP-TPU config of architecture 1 (it has stem_width): this version builds "
                             f"architecture {ARCHITECTURE} only; retrain the model (dptpu train)")
        known = set(cls.__dataclass_fields__)
        unknown = set(values) - known
        if unknown:
            raise ValueError(f"unknown DP-TPU config keys {sorted(unknown)}; expected some of {sorted(known)}")
        fields: dict[str, Any] = {k: tuple(v) if isinstance(v, list) else v for k, v in values.items()}
        return cls(**fields)  # keys checked above, values by __post_init__


def _median3(a: torch.Tensor, b: torch.Tensor, c: torch.Tensor) -> torch.Tensor:
    """Elementwise median of three tensors (Min/Max only)."""
    return torch.maximum(torch.minimum(a, b), torch.minimum(torch.maximum(a, b), c))


def median9(values: list[torch.Tensor]) -> torch.Tensor:
    """Elementwise median of 9 equally shaped tensors with Min/Max only (exports as ONNX Min/Max).

    The median of 9 is the median of (the largest of the three row minima, the median of the three row
    medians, the smallest of the three row maxima), rows being ``values[0:3], [3:6], [6:9]``. Used at
    stride 4, where onnxruntime's TopK over a channel axis would cost more than the rest of the network.
    """
    if len(values) != 9:
        raise ValueError(f"median9 takes 9 tensors; got {len(values)}")
    lows, mids, highs = [], [], []
    for row in range(3):
        a, b, c = values[3 * row:3 * row + 3]
        low, high = torch.minimum(a, b), torch.maximum(a, b)
        lows.append(torch.minimum(low, c))
        highs.append(torch.maximum(high, c))
        mids.append(torch.maximum(low, torch.minimum(high, c)))
    largest_low = torch.maximum(torch.maximum(lows[0], lows[1]), lows[2])
    smallest_high = torch.minimum(torch.minimum(highs[0], highs[1]), highs[2])
    return _median3(largest_low, _median3(*mids), smallest_high)


def median3x3(x: torch.Tensor) -> torch.Tensor:
    """3x3 median of a ``(B, C, h, w)`` map (edge replication), by :func:`median9` of the shifted maps."""
    height, width = x.shape[-2], x.shape[-1]
    padded = F.pad(x, (1, 1, 1, 1), mode="replicate")
    return median9([padded[:, :, dy:dy + height, dx:dx + width] for dy in range(3) for dx in range(3)])


def patch_median(periods: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Median of the valid ones of 9 pixels of each 4x4 patch (rows and columns :data:`MEDIAN_OFFSETS`).

    Parameters
    ----------
    periods : (B, 1, H, W)
        ``u_c`` in periods, H and W multiples of 4; 0 marks an invalid pixel (the inference wrapper
        feeds 0 there; a valid pixel has ``u_c = 0`` only if both ``k_c`` and ``psi_h`` are exactly 0).

    Returns
    -------
    median : (B, 1, H/4, W/4)
        The median, right while at most 4 of the 9 pixels have a wrong order; 0 where fewer than 5 of
        the 9 are valid. Invalid samples are replaced by ``+-FILL`` alternately (a checkerboard over the
        3x3 samples), so a few invalid pixels at a mask border hardly move the median of the valid ones.
    weight : (B, 1, H/4, W/4)
        1 where at least 5 of the 9 samples are valid, else 0.
    """
    samples = [periods[:, :, dy::PATCH, dx::PATCH] for dy in MEDIAN_OFFSETS for dx in MEDIAN_OFFSETS]
    valid = [sample != 0 for sample in samples]
    filled = [torch.where(v, sample, torch.full_like(sample, FILL if index % 2 == 0 else -FILL))
              for index, (sample, v) in enumerate(zip(samples, valid))]
    count = valid[0].to(periods.dtype)
    for v in valid[1:]:
        count = count + v.to(periods.dtype)
    weight = (count >= 5).to(periods.dtype)
    return median9(filled) * weight, weight


def network_features(wrapped_high, wrapped_low, coarse_order, frequency_high):
    """Inputs of the x4 down step, from ``(B, 1, H, W)`` maps with H, W multiples of 32.

    Returns
    -------
    full : list of 5 (B, 1, H, W)
        ``sin psi_h, cos psi_h, sin psi_l, cos psi_l, clip(r - u_c, -4, 4)`` (elementwise maps; kept
        apart, since concatenating them would copy five full-resolution maps).
    coarse : (B, 2, H/4, W/4)
        The patch median of ``u_c`` divided by ``f_h`` (``[0, 1)``), and the patch median minus the 3x3
        median of patch medians, clipped to +-4 periods.
    deviation : (B, 1, H, W)
        ``r - u_c`` (periods, unclipped): what the gate ``g`` blends in.
    """
    periods = coarse_order + wrapped_high * (1.0 / TWO_PI)  # u_c, periods
    median, weight = patch_median(periods)  # (B, 1, H/4, W/4)
    # r: bilinear x4 upsampling of the medians of the patches with enough valid pixels, normalized by the
    # upsampled weights (normalized convolution); 0 far inside invalid areas
    def upsample(x: torch.Tensor) -> torch.Tensor:
        return F.interpolate(x, scale_factor=PATCH, mode="bilinear", align_corners=False)

    reference = upsample(median) / torch.clamp(upsample(weight), min=1e-6)
    deviation = reference - periods
    full = [torch.sin(wrapped_high), torch.cos(wrapped_high), torch.sin(wrapped_low), torch.cos(wrapped_low),
            torch.clamp(deviation, -CONSISTENCY_CLIP, CONSISTENCY_CLIP)]
    coarse = torch.cat([median / frequency_high.reshape(-1, 1, 1, 1),
                        torch.clamp(median - median3x3(median), -CONSISTENCY_CLIP, CONSISTENCY_CLIP)], dim=1)
    return full, coarse, deviation


def pad_to_multiple(x: torch.Tensor, multiple: int = PAD_MULTIPLE) -> torch.Tensor:
    """Pad the last two axes of ``(B, C, H, W)`` at the bottom/right by edge replication to a multiple."""
    height, width = x.shape[-2], x.shape[-1]
    pad_h = (multiple - height % multiple) % multiple
    pad_w = (multiple - width % multiple) % multiple
    return F.pad(x, (0, pad_w, 0, pad_h), mode="replicate")


class DPTPUNet(nn.Module):
    """DP-TPU: x4 patch embedding, LVT encoder, U-MixFormer decoder, x4 pixel shuffle; residual on ``u_c``.

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
        dw = config.decoder_width
        if dw % h[-1]:
            raise ValueError(f"DP-TPU decoder_width must be a multiple of heads[-1]; got {dw} and {h[-1]}")
        self.patch_embed = nn.Conv2d(FULL_RES_CHANNELS, w[0], PATCH, stride=PATCH)  # x4 down
        self.embed = nn.ModuleList([
            nn.Sequential(nn.Conv2d(w[0] + PATCH_CHANNELS, w[0], 1), ChannelNorm(w[0])),  # + stride-4 maps
            *[nn.Sequential(nn.Conv2d(w[i - 1], w[i], 3, stride=2, padding=1), ChannelNorm(w[i])) for i in (1, 2, 3)],
        ])
        stages = [nn.Sequential(*[EncoderBlock(w[0], ConvSelfAttention(w[0], h[0]), config.mlp_ratio)
                                  for _ in range(d[0])])]
        for i in (1, 2, 3):
            stages.append(nn.Sequential(*[
                EncoderBlock(w[i], RecursiveAtrousSelfAttention(w[i], h[i], config.reductions[i - 1],
                                                                config.recursions), config.mlp_ratio)
                for _ in range(d[i])]))
        self.stages = nn.ModuleList(stages)
        self.lateral = nn.ModuleList([nn.Conv2d(w[i], dw, 1) for i in range(4)])
        self.decoder = nn.ModuleList([MixAttention(dw, 4 * dw, h[-1], config.mlp_ratio) for _ in range(4)])
        self.fuse = nn.Sequential(nn.Conv2d(dw, dw, 1), nn.GELU())
        # x4 up: a (correction) and g (gate), 16 channels each, then pixel shuffle; zero start
        self.head_correction = nn.Conv2d(dw, PATCH * PATCH, 1)
        self.head_gate = nn.Conv2d(dw, PATCH * PATCH, 1)
        for layer in (self.head_correction, self.head_gate):
            for parameter in layer.parameters():  # weight and bias
                nn.init.zeros_(parameter)

    def forward(self, wrapped_high, wrapped_low, coarse_order, frequency_high):
        height, width = wrapped_high.shape[-2], wrapped_high.shape[-1]
        padded = [pad_to_multiple(x) for x in (wrapped_high, wrapped_low, coarse_order)]
        full, coarse, deviation = network_features(*padded, frequency_high)
        decoded = self._decode(torch.cat([self._patch_embedding(full), coarse], dim=1))  # (B, D, H/4, W/4)
        correction = F.pixel_shuffle(self.head_correction(decoded), PATCH)  # (B, 1, H, W), x4 up
        gate = F.pixel_shuffle(F.conv2d(decoded, self.head_gate.weight * GATE_GAIN,
                                        self.head_gate.bias * GATE_GAIN), PATCH)
        delta = correction + gate * deviation  # u - u_c
        return coarse_order + delta[:, :, :height, :width]

    def _patch_embedding(self, full: list[torch.Tensor]) -> torch.Tensor:
        """The 4x4 stride-4 convolution of the five full-resolution maps, as a sum of one convolution per
        map (the same weights; no concatenated full-resolution copy): ``(B, w0, H/4, W/4)``."""
        weight = self.patch_embed.weight  # (w0, 5, 4, 4)
        out = F.conv2d(full[0], weight[:, :1], self.patch_embed.bias, stride=PATCH)
        for index in range(1, len(full)):
            out = out + F.conv2d(full[index], weight[:, index:index + 1], stride=PATCH)
        return out

    def _decode(self, x: torch.Tensor) -> torch.Tensor:
        """Encoder + decoder at strides 4-32: ``(B, C_in, h, w) -> (B, D, h, w)`` (stride 4)."""
        features: list[torch.Tensor] = []
        for embed, stage in zip(self.embed, self.stages):
            x = stage(embed(x if not features else features[-1]))
            features.append(x)  # strides 4, 8, 16, 32
        maps = [lateral(f) for lateral, f in zip(self.lateral, features)]  # each (B, D, H/s, W/s)
        for i in (3, 2, 1, 0):  # U-MixFormer: deepest stage first
            pool = [2 ** (3 - j) * self.config.decoder_pool for j in range(4)]
            mixed = torch.cat([F.avg_pool2d(m, p, ceil_mode=True) if p > 1 else m for m, p in zip(maps, pool)],
                              dim=1)  # ceil_mode: same size at every stride, any input size
            maps[i] = self.decoder[i](maps[i], mixed)
        fused = maps[0] + sum(F.interpolate(maps[i], scale_factor=2 ** i, mode="bilinear", align_corners=False)
                              for i in (1, 2, 3))
        return self.fuse(fused)  # (B, D, H/4, W/4)
