"""The DP-TPU inference graph (architecture 2) written op by op from the trained weights: ONNX without torch tracing.

:func:`build_dptpu_graph` turns the ``state_dict`` of a :class:`~dptpu.models.network.DPTPUNet` into an ONNX graph
that computes the same function as ``DPTPUNet.forward`` (docs/network.md; parity with torch < 1e-3 fringe orders,
tested) with a quarter of the nodes of the traced export and fewer full-resolution passes:

- **Space-to-depth**: the full-resolution maps are rearranged once into ``(B, 16, H/4, W/4)`` (channel
  ``4 dy + dx`` holds pixel ``(4 i + dy, 4 j + dx)``), and every full-resolution step is an elementwise op on
  that layout. The 4x4 stride-4 patch embedding becomes 1x1 convolutions (plain matrix products, no im2col), the
  patch-median samples a channel ``Gather``, the bilinear x4 upsampling of the reference ``r`` a 3x3 convolution
  with 16 fixed output kernels (align_corners = False: sub-pixel ``j`` of patch ``i`` blends patches ``i - 1, i``
  with weights ``(3/8, 5/8)``, ``(1/8, 7/8)`` for ``j = 0, 1`` and ``i, i + 1`` with ``(7/8, 1/8)``, ``(5/8, 3/8)``
  for ``j = 2, 3``; edge replication at the border), and the two pixel shuffles of the output one
  ``DepthToSpace`` of ``u - psi_h / 2 pi``.
- **Folded linear maps** (exact up to float rounding): the patch embedding into the 1x1 convolution after it; the
  affine part of every channel norm into the 1x1 convolutions that read it; the attention scale ``d^-1/2`` into
  the query convolution; with one head, the output projection and its bias into the value half of the key/value
  convolution (the softmax weights sum to 1); ``GATE_GAIN`` into the gate.
- **Static shapes**: reshapes use ``0`` / ``-1`` and a block input's shape, instead of the tracer's per-op
  ``Shape``/``Gather``/``Concat`` chains; the attention is written ``q^T k`` and ``a v^T`` so that onnxruntime
  fuses the transposes into its matrix products; the sorting networks work on stacked channels, and maxima,
  minima and sums over a few channels are variadic ``Max``/``Min``/``Sum`` of their slices (onnxruntime's
  reductions over the channel axis of NCHW are slow); the CSA window softmax is normalized after the weighted
  sum.
- The decoder pools each stage's map to the key stride once (the traced graph pools all four maps for each of
  the four decoder stages).

The graph holds only the folded constants; :func:`dptpu.models.export.export_onnx` stores the raw parameters beside
it under their ``state_dict`` names (the model's ``training_info``, which onnxruntime ignores), so
:func:`dptpu.models.onnx_weights.load_onnx_model` reads the weights of such a file by name.
"""
from __future__ import annotations

import numpy as np

__all__ = ["GRAPH_FORMAT", "build_dptpu_graph"]

#: ``graph`` metadata value of files built here (the traced export has none).
GRAPH_FORMAT = "dptpu-fast/1"
_INT_MAX = np.iinfo(np.int64).max
#: Bilinear x4 upsampling (align_corners = False) in 1-D: weights of patches ``i - 1, i, i + 1`` for sub-pixel j.
_UPSAMPLE_1D = np.array([[3, 5, 0], [1, 7, 0], [0, 7, 1], [0, 5, 3]], dtype=np.float64) / 8.0


class _Graph:
    """Nodes and initializers of the graph being written; every tensor gets a fresh name."""

    def __init__(self):
        self.nodes, self.initializers, self._count = [], {}, 0
        self.scope = ""  # prefix of node names (profiles group by it)

    def name(self, hint: str) -> str:
        self._count += 1
        return f"{self.scope}{hint}_{self._count}"

    def const(self, value, dtype=np.float32, hint: str = "fast") -> str:
        name = self.name(hint)
        self.initializers[name] = np.ascontiguousarray(np.asarray(value, dtype=dtype))
        return name

    def ints(self, *values) -> str:
        return self.const(np.array(values, dtype=np.int64), dtype=np.int64, hint="ints")

    def op(self, op_type: str, inputs, outputs: int = 1, **attrs):
        from onnx import helper  # an optional dependency (training)

        names = [self.name(op_type) for _ in range(outputs)]
        self.nodes.append(helper.make_node(op_type, list(inputs), names, name=names[0], **attrs))
        return names[0] if outputs == 1 else names

    # -- layers ---------------------------------------------------------------------------------------------
    def conv(self, x: str, weight, bias=None, **attrs) -> str:
        inputs = [x, self.const(weight)] + ([self.const(bias)] if bias is not None else [])
        return self.op("Conv", inputs, **attrs)

    def normalize(self, x: str, channels: int) -> str:
        """``(x - mean) / sqrt(var + 1e-6)`` over the channel axis of a (B, C, h, w) map (ChannelNorm, no affine).

        The centering is one 1x1 convolution (``I - 1/C``) and the variance's mean another (cheaper than
        onnxruntime's ReduceMean over the channel axis of NCHW).
        """
        centered = self.conv(x, (np.eye(channels) - 1.0 / channels).reshape(channels, channels, 1, 1))
        var = self.conv(self.op("Mul", [centered, centered]), np.full((1, channels, 1, 1), 1.0 / channels))
        return self.op("Div", [centered, self.op("Sqrt", [self.op("Add", [var, self.const(1e-6)])])])

    def affine(self, x: str, weight, bias) -> str:
        scale = np.asarray(weight).reshape(1, -1, 1, 1)
        shift = np.asarray(bias).reshape(1, -1, 1, 1)
        return self.op("Add", [self.op("Mul", [x, self.const(scale)]), self.const(shift)])

    def gelu(self, x: str) -> str:
        """Exact GELU written as the pattern onnxruntime fuses into one kernel."""
        erf = self.op("Erf", [self.op("Div", [x, self.const(np.sqrt(2.0))])])
        return self.op("Mul", [self.op("Mul", [x, self.op("Add", [erf, self.const(1.0)])]), self.const(0.5)])

    def split(self, x: str, parts: int) -> list[str]:
        """``parts`` single-channel slices of a (B, parts, h, w) map."""
        return self.op("Split", [x, self.ints(*[1] * parts)], outputs=parts, axis=1)

    def median3(self, a: str, b: str, c: str) -> str:
        return self.op("Max", [self.op("Min", [a, b]), self.op("Min", [self.op("Max", [a, b]), c])])

    def median9(self, stacked: str) -> str:
        """Median over the 9 channels of (B, 9, h, w), by :func:`dptpu.models.network.median9`'s network applied to
        the triples ``(t, t + 3, t + 6)`` at once (the median of 9 is that network's result for any triples)."""
        a, b, c = self.op("Split", [stacked, self.ints(3, 3, 3)], outputs=3, axis=1)
        low_ab, high_ab = self.op("Min", [a, b]), self.op("Max", [a, b])
        lows = self.op("Min", [low_ab, c])
        highs = self.op("Max", [high_ab, c])
        mids = self.op("Max", [low_ab, self.op("Min", [high_ab, c])])
        largest_low = self.op("Max", self.split(lows, 3))  # variadic Max of slices: cheaper than ReduceMax
        smallest_high = self.op("Min", self.split(highs, 3))
        mid = self.median3(*self.split(mids, 3))
        return self.median3(largest_low, mid, smallest_high)


def _w(p, key) -> np.ndarray:
    return np.asarray(p[key], dtype=np.float64)


def _fold_norm(weight, bias, norm_weight, norm_bias):
    """1x1 conv ``(W, b)`` applied to ``norm_weight * x + norm_bias``: the same conv applied to ``x``."""
    weight2 = weight.reshape(weight.shape[0], -1)
    return (weight2 * norm_weight[None, :]).reshape(weight.shape), bias + weight2 @ norm_bias


def _attention(g: _Graph, q: str, kv: str, shape: str, channels: int, heads: int) -> str:
    """Multi-head attention of a (B, C, h, w) query map (already scaled) over a (B, 2C, ...) key/value map.

    Returns the (B, C, h, w) output (``shape``: the query map's shape).
    """
    d = channels // heads
    q = g.op("Reshape", [q, g.ints(0, heads, d, -1)])  # (B, heads, d, Nq)
    k, v = g.op("Split", [g.op("Reshape", [kv, g.ints(0, 2 * heads, d, -1)]), g.ints(heads, heads)], outputs=2,
                axis=1)  # each (B, heads, d, Nk)
    scores = g.op("MatMul", [g.op("Transpose", [q], perm=[0, 1, 3, 2]), k])  # (B, heads, Nq, Nk)
    weights = g.op("Softmax", [scores], axis=-1)
    out = g.op("MatMul", [weights, g.op("Transpose", [v], perm=[0, 1, 3, 2])])  # (B, heads, Nq, d)
    return g.op("Reshape", [g.op("Transpose", [out], perm=[0, 1, 3, 2]), shape])  # (B, heads, d, Nq) -> (B, C, h, w)


def _key_value(p, prefix: str, heads: int, norm=None):
    """Weights of the key/value 1x1 conv, with the channel norm's affine and (one head) the projection folded."""
    weight, bias = _w(p, prefix + "key_value.weight"), _w(p, prefix + "key_value.bias")
    if norm is not None:
        weight, bias = _fold_norm(weight, bias, *norm)
    if heads != 1:
        return weight, bias, False
    c = weight.shape[0] // 2
    proj_w, proj_b = _w(p, prefix + "proj.weight").reshape(c, c), _w(p, prefix + "proj.bias")
    value_w = proj_w @ weight[c:].reshape(c, -1)
    weight = np.concatenate([weight[:c].reshape(c, -1), value_w]).reshape(weight.shape)
    bias = np.concatenate([bias[:c], proj_w @ bias[c:] + proj_b])  # softmax rows sum to 1: the bias passes
    return weight, bias, True


def _query(p, prefix: str, heads: int, norm=None):
    weight, bias = _w(p, prefix + "query.weight"), _w(p, prefix + "query.bias")
    if norm is not None:
        weight, bias = _fold_norm(weight, bias, *norm)
    scale = (weight.shape[0] // heads) ** -0.5
    return weight * scale, bias * scale


def _mlp(g: _Graph, p, prefix: str, x: str, norm) -> str:
    """``x + MixFFN(norm(x))`` with the norm's affine folded into fc1."""
    fc1_w, fc1_b = _fold_norm(_w(p, prefix + "mlp.fc1.weight"), _w(p, prefix + "mlp.fc1.bias"), *norm)
    hidden = g.conv(g.normalize(x, fc1_w.shape[1]), fc1_w, fc1_b)
    dw = _w(p, prefix + "mlp.dw.weight")
    hidden = g.gelu(g.conv(hidden, dw, _w(p, prefix + "mlp.dw.bias"), pads=[1, 1, 1, 1], group=dw.shape[0]))
    return g.op("Add", [x, g.conv(hidden, _w(p, prefix + "mlp.fc2.weight"), _w(p, prefix + "mlp.fc2.bias"))])


def _norm_params(p, prefix: str):
    return _w(p, prefix + ".weight"), _w(p, prefix + ".bias")


def _csa_block(g: _Graph, p, prefix: str, x: str, heads: int) -> str:
    """Encoder block of stage 1: Convolutional Self-Attention over 3x3 windows, then the Mix-FFN."""
    norm1 = _norm_params(p, prefix + "norm1")
    xn = g.normalize(x, len(norm1[0]))
    attn_w, attn_b = _fold_norm(_w(p, prefix + "attention.attn.weight"), _w(p, prefix + "attention.attn.bias"), *norm1)
    value_w, value_b = _fold_norm(_w(p, prefix + "attention.value.weight"), _w(p, prefix + "attention.value.bias"),
                                  *norm1)
    channels, k2 = value_w.shape[0], attn_w.shape[0] // heads
    kernel = round(float(np.sqrt(k2)))
    r = kernel // 2
    logits = g.conv(xn, attn_w, attn_b)  # (B, heads * k2, h, w)
    value = g.op("Pad", [g.conv(xn, value_w, value_b), g.ints(0, 0, r, r, 0, 0, r, r)], mode="constant")
    head_logits = g.op("Split", [logits, g.ints(*[k2] * heads)], outputs=heads, axis=1) if heads > 1 else [logits]
    head_values = (g.op("Split", [value, g.ints(*[channels // heads] * heads)], outputs=heads, axis=1)
                   if heads > 1 else [value])
    outs = []
    for logit, val in zip(head_logits, head_values):
        # softmax over the window, normalized after the weighted sum: sum_k e_k v_k / sum_k e_k
        e = g.split(g.op("Exp", [g.op("Sub", [logit, g.op("Max", g.split(logit, k2))])]), k2)
        out = None
        for index in range(k2):
            dy, dx = divmod(index, kernel)
            ends = [-(2 * r - dy) if dy < 2 * r else _INT_MAX, -(2 * r - dx) if dx < 2 * r else _INT_MAX]
            window = g.op("Slice", [val, g.ints(dy, dx), g.ints(*ends), g.ints(2, 3)])
            term = g.op("Mul", [e[index], window])
            out = term if out is None else g.op("Add", [out, term])
        outs.append(g.op("Div", [out, g.op("Sum", e)]))
    out = outs[0] if heads == 1 else g.op("Concat", outs, axis=1)
    x = g.op("Add", [x, g.conv(out, _w(p, prefix + "attention.proj.weight"), _w(p, prefix + "attention.proj.bias"))])
    return _mlp(g, p, prefix, x, _norm_params(p, prefix + "norm2"))


def _rasa_block(g: _Graph, p, prefix: str, x: str, heads: int, reduction: int, recursions: int) -> str:
    """Encoder block of stages 2-4: Recursive Atrous Self-Attention, then the Mix-FFN."""
    norm1 = _norm_params(p, prefix + "norm1")
    xa = g.affine(g.normalize(x, len(norm1[0])), *norm1)
    a = prefix + "attention."
    query_dw = _w(p, a + "query_dw")
    channels = query_dw.shape[0]
    query_w, query_b = _query(p, a, heads)
    kv_w, kv_b, folded = _key_value(p, a, heads)
    shape = g.op("Shape", [x])

    def attend(z):
        q = None
        for dilation in (1, 3, 5):
            term = g.conv(z, query_dw, pads=[dilation] * 4, dilations=[dilation, dilation], group=channels)
            q = term if q is None else g.op("Add", [q, term])
        q = g.conv(q, query_w, query_b)
        pooled = (g.op("AveragePool", [z], kernel_shape=[reduction] * 2, strides=[reduction] * 2, ceil_mode=1)
                  if reduction > 1 else z)
        out = _attention(g, q, g.conv(pooled, kv_w, kv_b), shape, channels, heads)
        return out if folded else g.conv(out, _w(p, a + "proj.weight"), _w(p, a + "proj.bias"))

    out = attend(xa)
    for _ in range(recursions - 1):
        out = attend(g.op("Add", [xa, out]))
    x = g.op("Add", [x, out])
    return _mlp(g, p, prefix, x, _norm_params(p, prefix + "norm2"))


def _mix_attention(g: _Graph, p, prefix: str, query: str, mixed: str, heads: int) -> str:
    """U-MixFormer decoder stage (query map, mixed key/value map) -> (B, D, h, w)."""
    query_w, query_b = _query(p, prefix, heads, _norm_params(p, prefix + "norm_q"))
    kv_w, kv_b, folded = _key_value(p, prefix, heads, _norm_params(p, prefix + "norm_kv"))
    q = g.conv(g.normalize(query, query_w.shape[1]), query_w, query_b)
    key_value = g.conv(g.normalize(mixed, kv_w.shape[1]), kv_w, kv_b)
    out = _attention(g, q, key_value, g.op("Shape", [query]), query_w.shape[0], heads)
    if not folded:
        out = g.conv(out, _w(p, prefix + "proj.weight"), _w(p, prefix + "proj.bias"))
    return _mlp(g, p, prefix, g.op("Add", [query, out]), _norm_params(p, prefix + "norm_mlp"))


def _upsample_kernels() -> np.ndarray:
    """(16, 1, 3, 3): output channel ``4 jy + jx`` is sub-pixel (jy, jx) of the bilinear x4 upsampling."""
    kernels = np.einsum("ay,bx->abyx", _UPSAMPLE_1D, _UPSAMPLE_1D)  # (4, 4, 3, 3)
    return kernels.reshape(16, 1, 3, 3)


def _window_kernels(order) -> np.ndarray:
    """(9, 1, 3, 3) one-hot kernels: output channel ``n`` copies the 3x3 window's pixel ``order[n]`` (dy, dx)."""
    kernels = np.zeros((9, 1, 3, 3))
    for n, (dy, dx) in enumerate(order):
        kernels[n, 0, dy, dx] = 1.0
    return kernels


def build_dptpu_graph(state: dict, config):
    """The ONNX graph of a DP-TPU network (architecture 2) with the weights ``state``.

    Parameters
    ----------
    state : dict
        ``state_dict`` of a :class:`~dptpu.models.network.DPTPUNet` (tensors or arrays).
    config : DPTPUConfig

    Returns
    -------
    onnx.GraphProto
        Inputs ``wrapped_high``, ``wrapped_low``, ``coarse_order`` ``(B, 1, H, W)`` float32 and
        ``frequency_high`` ``(B,)``; output ``fringe_order`` ``(B, 1, H, W)``: the continuous fringe order of
        ``DPTPUNet.forward`` (:mod:`dptpu.models.export`).
    """
    from onnx import TensorProto, helper, numpy_helper  # an optional dependency (training)

    from .network import (  # torch: the inference side imports this module without it
        CONSISTENCY_CLIP,
        FILL,
        GATE_GAIN,
        MEDIAN_OFFSETS,
        PAD_MULTIPLE,
        PATCH,
        TWO_PI,
    )

    if PATCH != 4:
        raise ValueError(f"the fast graph is written for 4x4 patches; PATCH is {PATCH}")
    p = {key: np.asarray(value.detach().cpu().numpy() if hasattr(value, "detach") else value, dtype=np.float64)
         for key, value in state.items()}
    g = _Graph()
    g.scope = "full."
    names = ("wrapped_high", "wrapped_low", "coarse_order")
    # pad height and width at the bottom/right to multiples of 32 by edge replication, then space-to-depth
    hw = g.op("Slice", [g.op("Shape", ["wrapped_high"]), g.ints(2), g.ints(4)])
    pads = g.op("Concat", [g.ints(0, 0, 0, 0, 0, 0), g.op("Mod", [g.op("Neg", [hw]), g.ints(PAD_MULTIPLE)], fmod=0)],
                axis=0)
    psi_h, psi_l, coarse = (g.op("SpaceToDepth", [g.op("Pad", [name, pads], mode="edge")], blocksize=PATCH)
                            for name in names)  # (B, 16, h, w)
    periods = g.op("Add", [coarse, g.op("Mul", [psi_h, g.const(1.0 / TWO_PI)])])  # u_c
    # patch median of 9 samples; invalid (0) samples stand in as +-FILL by their row-major index's parity
    order = [(dy, dx) for dy in MEDIAN_OFFSETS for dx in MEDIAN_OFFSETS]  # row-major, as patch_median
    fill = np.array([FILL if n % 2 == 0 else -FILL for n in range(9)]).reshape(1, 9, 1, 1)
    samples = g.op("Gather", [periods, g.ints(*[dy * PATCH + dx for dy, dx in order])], axis=1)  # (B, 9, h, w)
    invalid = g.op("Cast", [g.op("Equal", [samples, g.const(0.0)])], to=TensorProto.FLOAT)  # 1 where invalid
    count_invalid = g.op("ReduceSum", [invalid, g.ints(1)], keepdims=1)
    weight = g.op("Cast", [g.op("LessOrEqual", [count_invalid, g.const(4.0)])], to=TensorProto.FLOAT)
    filled = g.op("Add", [samples, g.op("Mul", [invalid, g.const(fill)])])  # an invalid sample is 0: 0 + fill
    median = g.op("Mul", [g.median9(filled), weight])  # (B, 1, h, w)
    # reference r: bilinear x4 upsampling (16 sub-pixel kernels) of the weighted medians over that of the weights
    up_median, up_weight = (g.conv(g.op("Pad", [m, g.ints(0, 0, 1, 1, 0, 0, 1, 1)], mode="edge"), _upsample_kernels())
                            for m in (median, weight))
    reference = g.op("Div", [up_median, g.op("Max", [up_weight, g.const(1e-6)])])
    deviation = g.op("Sub", [reference, periods])  # r - u_c, (B, 16, h, w)
    full = [g.op("Sin", [psi_h]), g.op("Cos", [psi_h]), g.op("Sin", [psi_l]), g.op("Cos", [psi_l]),
            g.op("Clip", [deviation, g.const(-CONSISTENCY_CLIP), g.const(CONSISTENCY_CLIP)])]
    # stride-4 maps: m / f_h and clip(m - median3x3(m))
    g.scope = "stride4."
    frequency = g.op("Reshape", ["frequency_high", g.ints(-1, 1, 1, 1)])
    windows = g.conv(g.op("Pad", [median, g.ints(0, 0, 1, 1, 0, 0, 1, 1)], mode="edge"),
                     _window_kernels([(dy, dx) for dy in range(3) for dx in range(3)]))
    neighbourhood = g.op("Clip", [g.op("Sub", [median, g.median9(windows)]), g.const(-CONSISTENCY_CLIP),
                                  g.const(CONSISTENCY_CLIP)])
    stride4 = g.op("Concat", [g.op("Div", [median, frequency]), neighbourhood], axis=1)
    # patch embedding folded into embed.0's 1x1 conv
    cfg = config
    w0 = cfg.widths[0]
    embed_w, embed_b = _w(p, "embed.0.0.weight").reshape(w0, -1), _w(p, "embed.0.0.bias")
    patch_w, patch_b = _w(p, "patch_embed.weight"), _w(p, "patch_embed.bias")  # (w0, 5, 4, 4)
    g.scope = "embed."
    x = g.conv(stride4, embed_w[:, w0:].reshape(w0, -1, 1, 1), embed_b + embed_w[:, :w0] @ patch_b)
    for index, feature in enumerate(full):
        folded = embed_w[:, :w0] @ patch_w[:, index].reshape(patch_w.shape[0], PATCH * PATCH)
        x = g.op("Add", [x, g.conv(feature, folded.reshape(w0, PATCH * PATCH, 1, 1))])
    x = g.affine(g.normalize(x, w0), *_norm_params(p, "embed.0.1"))
    features: list[str] = []  # value names of the encoder's stage outputs
    for stage in range(4):
        if stage > 0:
            x = g.conv(features[-1], _w(p, f"embed.{stage}.0.weight"), _w(p, f"embed.{stage}.0.bias"),
                       pads=[1, 1, 1, 1], strides=[2, 2])
            x = g.affine(g.normalize(x, cfg.widths[stage]), *_norm_params(p, f"embed.{stage}.1"))
        for block in range(cfg.depths[stage]):
            prefix = f"stages.{stage}.{block}."
            g.scope = prefix
            if stage == 0:
                x = _csa_block(g, p, prefix, x, cfg.heads[0])
            else:
                x = _rasa_block(g, p, prefix, x, cfg.heads[stage], cfg.reductions[stage - 1], cfg.recursions)
        features.append(x)
    maps = [g.conv(f, _w(p, f"lateral.{i}.weight"), _w(p, f"lateral.{i}.bias")) for i, f in enumerate(features)]
    pools = [2 ** (3 - j) * cfg.decoder_pool for j in range(4)]

    def pool(m, size):
        return g.op("AveragePool", [m], kernel_shape=[size] * 2, strides=[size] * 2, ceil_mode=1) if size > 1 else m

    pooled = [pool(m, s) for m, s in zip(maps, pools)]
    for i in (3, 2, 1, 0):
        g.scope = f"decoder.{i}."
        maps[i] = _mix_attention(g, p, f"decoder.{i}.", maps[i], g.op("Concat", pooled, axis=1), cfg.heads[-1])
        if i:
            pooled[i] = pool(maps[i], pools[i])
    g.scope = "head."
    fused = maps[0]
    for i in (1, 2, 3):
        scale = float(2 ** i)
        fused = g.op("Add", [fused, g.op("Resize", [maps[i], "", g.const([1.0, 1.0, scale, scale])], mode="linear",
                                         coordinate_transformation_mode="half_pixel")])
    decoded = g.gelu(g.conv(fused, _w(p, "fuse.0.weight"), _w(p, "fuse.0.bias")))
    correction = g.conv(decoded, _w(p, "head_correction.weight"), _w(p, "head_correction.bias"))
    gate = g.conv(decoded, _w(p, "head_gate.weight") * GATE_GAIN, _w(p, "head_gate.bias") * GATE_GAIN)
    delta = g.op("Add", [correction, g.op("Mul", [gate, deviation])])  # u - u_c, (B, 16, h, w)
    order_map = g.op("DepthToSpace", [g.op("Add", [coarse, delta])], blocksize=PATCH, mode="CRD")
    g.nodes.append(helper.make_node("Slice", [order_map, g.ints(0, 0), hw, g.ints(2, 3)], ["fringe_order"]))
    initializers = [numpy_helper.from_array(v, name=k) for k, v in g.initializers.items()]

    def image(name: str):
        return helper.make_tensor_value_info(name, TensorProto.FLOAT, ["batch", 1, "height", "width"])

    inputs = [image(name) for name in names] + [helper.make_tensor_value_info("frequency_high", TensorProto.FLOAT,
                                                                              ["batch"])]
    return helper.make_graph(g.nodes, "dptpu_fast", inputs, [image("fringe_order")], initializer=initializers)
