"""Building blocks of the DP-TPU network: channel LayerNorm, MLP, CSA, RASA and cross attention.

Every block works on ``(B, C, H, W)`` feature maps and uses only ops that export to ONNX (opset 18) with
dynamic height and width: 1x1 / 3x3 / depthwise convolutions, slicing of a padded map, softmax, matmul,
reshape, average pooling with a fixed kernel, and interpolation by a fixed scale factor.

References
----------
DP-TPU paper, Fig. 9a and section "Physics-aware generalized temporal phase unwrapping deep neural
network"; Lite Vision Transformer (LVT, Yang et al. 2022: Convolutional Self-Attention, Recursive Atrous
Self-Attention); U-MixFormer (Yeom & von Klitzing 2023: mixed attention decoder).
"""
from __future__ import annotations

import torch
from torch import nn
from torch.nn import functional as F

__all__ = [
    "ChannelNorm",
    "ConvMLP",
    "ConvSelfAttention",
    "EncoderBlock",
    "MixAttention",
    "RecursiveAtrousSelfAttention",
]


class ChannelNorm(nn.Module):
    """LayerNorm over the channel axis of a ``(B, C, H, W)`` map (per pixel), with affine weight and bias."""

    def __init__(self, channels: int, eps: float = 1e-6):
        super().__init__()
        self.weight = nn.Parameter(torch.ones(channels))
        self.bias = nn.Parameter(torch.zeros(channels))
        self.eps = eps

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        mean = x.mean(dim=1, keepdim=True)  # (B, 1, H, W)
        centered = x - mean
        var = (centered * centered).mean(dim=1, keepdim=True)
        x = centered / torch.sqrt(var + self.eps)
        return x * self.weight[None, :, None, None] + self.bias[None, :, None, None]


class ConvMLP(nn.Module):
    """Mix-FFN: 1x1 expand, depthwise 3x3 (positional information), GELU, 1x1 project."""

    def __init__(self, channels: int, ratio: int = 2):
        super().__init__()
        hidden = channels * ratio
        self.fc1 = nn.Conv2d(channels, hidden, 1)
        self.dw = nn.Conv2d(hidden, hidden, 3, padding=1, groups=hidden)
        self.fc2 = nn.Conv2d(hidden, channels, 1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.fc2(F.gelu(self.dw(self.fc1(x))))


class ConvSelfAttention(nn.Module):
    """Convolutional Self-Attention (CSA) of LVT stage 1: attention over each pixel's local window.

    Every pixel's query produces, per head, a softmax over the ``kernel**2`` pixels of its window; the
    output is that weighted sum of the window's values (a content-dependent local convolution, which
    keeps the fine detail a fringe-order edge needs).
    """

    def __init__(self, channels: int, heads: int, kernel: int = 3):
        super().__init__()
        if channels % heads:
            raise ValueError(f"CSA channels must be a multiple of heads; got {channels} and {heads}")
        self.heads, self.kernel = heads, kernel
        self.attn = nn.Conv2d(channels, heads * kernel * kernel, 1)
        self.value = nn.Conv2d(channels, channels, 1)
        self.proj = nn.Conv2d(channels, channels, 1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        b, c, h, w = x.shape
        k2, r = self.kernel * self.kernel, self.kernel // 2
        logits = self.attn(x).reshape(b, self.heads, k2, h, w)  # (B, heads, k2, H, W)
        # softmax over the window axis written out: onnxruntime's Softmax on a middle axis transposes
        weights = torch.exp(logits - logits.amax(dim=2, keepdim=True))
        weights = weights / weights.sum(dim=2, keepdim=True)
        padded = F.pad(self.value(x), (r, r, r, r)).reshape(b, self.heads, c // self.heads, h + 2 * r, w + 2 * r)
        out = weights[:, :, 0:1] * padded[:, :, :, 0:h, 0:w]  # window position 0: (dy, dx) = (0, 0)
        for index in range(1, k2):  # weighted sum of the shifted value maps (slices, no 6-D transpose)
            dy, dx = divmod(index, self.kernel)
            out = out + weights[:, :, index:index + 1] * padded[:, :, :, dy:dy + h, dx:dx + w]
        return self.proj(out.reshape(b, c, h, w))  # out: (B, heads, C/heads, H, W)


def _attention(q: torch.Tensor, k: torch.Tensor, v: torch.Tensor, heads: int) -> torch.Tensor:
    """Multi-head scaled dot-product attention of token maps.

    q : (B, C, Nq), k and v : (B, C, Nk) -> (B, C, Nq).
    """
    b, c, nq = q.shape
    nk = k.shape[-1]
    d = c // heads
    q = q.reshape(b, heads, d, nq).transpose(2, 3)  # (B, heads, Nq, d)
    k = k.reshape(b, heads, d, nk)  # (B, heads, d, Nk)
    v = v.reshape(b, heads, d, nk).transpose(2, 3)  # (B, heads, Nk, d)
    attn = torch.matmul(q * (d ** -0.5), k).softmax(dim=-1)  # (B, heads, Nq, Nk); scale the smaller q
    return torch.matmul(attn, v).transpose(2, 3).reshape(b, c, nq)


class RecursiveAtrousSelfAttention(nn.Module):
    """Recursive Atrous Self-Attention (RASA) of LVT stages 2-4.

    Queries come from one depthwise 3x3 kernel applied at dilations 1, 3 and 5 (shared weights, summed:
    multi-scale context at no extra parameters); keys and values from the map average-pooled by
    ``reduction`` (global attention at a bounded cost; ``ceil_mode``: a partial window at the border
    averages the pixels it has, so a map smaller than ``reduction`` still gives one key); the attention is
    applied ``recursions`` times with the same weights, feeding ``x + previous output`` back in.
    """

    def __init__(self, channels: int, heads: int, reduction: int = 1, recursions: int = 2,
                 dilations: tuple[int, ...] = (1, 3, 5)):
        super().__init__()
        if channels % heads:
            raise ValueError(f"RASA channels must be a multiple of heads; got {channels} and {heads}")
        self.heads, self.reduction, self.recursions, self.dilations = heads, reduction, recursions, dilations
        self.query_dw = nn.Parameter(torch.randn(channels, 1, 3, 3) * 0.1)
        self.query = nn.Conv2d(channels, channels, 1)
        self.key_value = nn.Conv2d(channels, 2 * channels, 1)
        self.proj = nn.Conv2d(channels, channels, 1)

    def _atrous_attention(self, x: torch.Tensor) -> torch.Tensor:
        b, c, h, w = x.shape
        q = sum(F.conv2d(x, self.query_dw, padding=d, dilation=d, groups=c) for d in self.dilations)
        q = self.query(q).reshape(b, c, h * w)
        pooled = F.avg_pool2d(x, self.reduction, ceil_mode=True) if self.reduction > 1 else x  # any size
        k, v = self.key_value(pooled).flatten(2).chunk(2, dim=1)  # each (B, C, N/r^2)
        return self.proj(_attention(q, k, v, self.heads).reshape(b, c, h, w))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        out = self._atrous_attention(x)
        for _ in range(self.recursions - 1):
            out = self._atrous_attention(x + out)
        return out


class EncoderBlock(nn.Module):
    """Pre-norm transformer block: ``x + attention(norm(x))`` then ``x + MLP(norm(x))``."""

    def __init__(self, channels: int, attention: nn.Module, mlp_ratio: int = 2):
        super().__init__()
        self.norm1, self.attention = ChannelNorm(channels), attention
        self.norm2, self.mlp = ChannelNorm(channels), ConvMLP(channels, mlp_ratio)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        x = x + self.attention(self.norm1(x))
        return x + self.mlp(self.norm2(x))


class MixAttention(nn.Module):
    """U-MixFormer decoder stage: one stage's features as queries, the mixed multi-scale map as keys/values.

    ``forward(query, mixed)``: query (B, D, H, W), mixed (B, D_mix, h, w) -> (B, D, H, W), with a
    pre-norm residual cross attention and a Mix-FFN.
    """

    def __init__(self, channels: int, mixed_channels: int, heads: int, mlp_ratio: int = 2):
        super().__init__()
        self.heads = heads
        self.norm_q, self.norm_kv = ChannelNorm(channels), ChannelNorm(mixed_channels)
        self.query = nn.Conv2d(channels, channels, 1)
        self.key_value = nn.Conv2d(mixed_channels, 2 * channels, 1)
        self.proj = nn.Conv2d(channels, channels, 1)
        self.norm_mlp, self.mlp = ChannelNorm(channels), ConvMLP(channels, mlp_ratio)

    def forward(self, query: torch.Tensor, mixed: torch.Tensor) -> torch.Tensor:
        b, c, h, w = query.shape
        q = self.query(self.norm_q(query)).reshape(b, c, h * w)
        k, v = self.key_value(self.norm_kv(mixed)).flatten(2).chunk(2, dim=1)
        x = query + self.proj(_attention(q, k, v, self.heads).reshape(b, c, h, w))
        return x + self.mlp(self.norm_mlp(x))
