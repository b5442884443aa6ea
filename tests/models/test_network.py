"""DP-TPU and U-Net architectures: output shapes for odd input sizes, the residual start, the stride-4
consistency features and the reference that repairs isolated wrong orders, config checks."""
import numpy as np
import pytest
import torch

from dptpu.models.factory import build_model
from dptpu.models.network import (
    GATE_GAIN,
    DPTPUConfig,
    DPTPUNet,
    median3x3,
    median9,
    network_features,
    patch_median,
)
from dptpu.models.unet_baseline import UNetBaseline

from .conftest import TINY_DPTPU, TINY_UNET, phase_inputs, randomize_head


def _tensors(shape, batch=2, seed=0):
    high, low, coarse, frequency = phase_inputs(shape, seed=seed, batch=batch)
    return (torch.from_numpy(high)[:, None], torch.from_numpy(low)[:, None], torch.from_numpy(coarse)[:, None],
            torch.from_numpy(frequency))


@pytest.mark.parametrize("kind,config", [("dptpu", TINY_DPTPU), ("unet", TINY_UNET)])
@pytest.mark.parametrize("shape", [(33, 47), (64, 64), (71, 30)])
def test_output_has_the_input_size_for_any_height_and_width(kind, config, shape):
    torch.manual_seed(0)
    model = build_model(kind, config).eval()
    with torch.no_grad():
        out = model(*_tensors(shape))
    assert out.shape == (2, 1, *shape) and out.dtype == torch.float32
    assert torch.isfinite(out).all()


def test_untrained_dptpu_returns_the_classical_order_exactly():
    """The last layer starts at zero: output = coarse order + 0 (the residual form)."""
    torch.manual_seed(0)
    model = build_model("dptpu", TINY_DPTPU).eval()
    inputs = _tensors((40, 56))
    with torch.no_grad():
        assert torch.equal(model(*inputs), inputs[2])


def test_output_at_a_pixel_depends_on_distant_pixels_through_attention():
    """Global context: changing the phase in one corner moves the prediction in the opposite corner."""
    torch.manual_seed(0)
    model = randomize_head(build_model("dptpu", TINY_DPTPU)).eval()
    high, low, coarse, frequency = _tensors((96, 96), batch=1)
    changed = high.clone()
    changed[..., :8, :8] = 0.0
    with torch.no_grad():
        a, b = model(high, low, coarse, frequency), model(changed, low, coarse, frequency)
    assert float((a - b)[..., -8:, -8:].abs().max()) > 1e-6


def test_unet_ignores_the_coarse_order_and_frequency():
    torch.manual_seed(0)
    model = UNetBaseline(UNetBaseline().config.__class__(widths=tuple(TINY_UNET["widths"]))).eval()
    high, low, coarse, frequency = _tensors((32, 32))
    with torch.no_grad():
        assert torch.equal(model(high, low, coarse, frequency), model(high, low, coarse * 0 + 7, frequency * 2))


def test_median9_and_median3x3_are_exact_medians():
    generator = torch.Generator().manual_seed(0)
    values = [torch.randn(3, 5, 7, generator=generator) for _ in range(9)]
    assert torch.equal(median9(values), torch.stack(values).median(dim=0).values)
    ties = [torch.tensor([1.0, 2.0])] * 5 + [torch.tensor([0.0, 9.0])] * 4
    assert median9(ties).tolist() == [1.0, 2.0]
    x = torch.arange(20, dtype=torch.float32).reshape(1, 1, 4, 5) ** 2 % 11
    got = median3x3(x)[0, 0]
    padded = torch.nn.functional.pad(x, (1, 1, 1, 1), mode="replicate")[0, 0]
    expected = torch.tensor([[float(padded[r:r + 3, c:c + 3].flatten().sort().values[4]) for c in range(5)]
                             for r in range(4)])
    assert torch.equal(got, expected)


def _ramp(height=32, width=64, errors=()):
    """A smooth absolute phase u = 3.3 + 0.1 x + 0.05 y (periods), its psi_h and true / coarse orders.

    ``errors``: (row, col, offset) of isolated wrong coarse orders.
    """
    y, x = np.mgrid[0:height, 0:width].astype(np.float64)
    u = 3.3 + 0.1 * x + 0.05 * y
    label = np.floor(u)
    psi_h = 2 * np.pi * (u - label)
    coarse = label.copy()
    for row, col, offset in errors:
        coarse[row, col] += offset

    def as_tensor(a: np.ndarray) -> torch.Tensor:
        return torch.from_numpy(a.astype(np.float32))[None, None]

    return as_tensor(psi_h), as_tensor(coarse), label


def test_features_flag_an_isolated_wrong_order_and_a_wrong_patch_by_their_offset_in_periods():
    psi_h, coarse, _ = _ramp(errors=[(5, 9, 1), (6, 30, -3)])
    coarse[..., 16:20, 40:44] += 2  # a whole 4x4 patch two orders off
    full, stride4, deviation = network_features(psi_h, psi_h * 0 + 1.0, coarse, torch.tensor([64.0]))
    assert [m.shape for m in full] == [(1, 1, 32, 64)] * 5
    assert stride4.shape == (1, 2, 8, 16) and deviation.shape == (1, 1, 32, 64)
    assert torch.allclose(full[0][0, 0], torch.sin(psi_h[0, 0]), atol=1e-6)
    assert torch.allclose(full[3][0, 0], torch.cos(torch.tensor(1.0)).expand(32, 64), atol=1e-6)
    # r - u_c: about -1 / +3 at the two isolated pixels (the patch medians ignore them), |.| < 0.3 elsewhere
    assert float(deviation[0, 0, 5, 9]) == pytest.approx(-1.0, abs=0.3)
    assert float(deviation[0, 0, 6, 30]) == pytest.approx(3.0, abs=0.3)
    # the wrong patch: its median is 2 periods above the 3x3 median of the patch medians
    assert float(stride4[0, 1, 4, 10]) == pytest.approx(2.0, abs=0.3)
    assert float(stride4[0, 1, 2, 2]) == pytest.approx(0.0, abs=0.3)
    assert float(stride4[0, 0, 2, 2]) == pytest.approx(float(patch_median(psi_h / (2 * np.pi) + coarse)[0][0, 0, 2, 2])
                                                       / 64.0)


def test_the_reference_alone_repairs_isolated_wrong_orders_on_a_smooth_surface():
    """Gate g = 1 everywhere (u = r): rounding r - psi_h/2pi gives the true order at every pixel of a
    smooth ramp, including 12 isolated pixels whose coarse order is off by -5 to +7 (the order is decided
    against each pixel's own psi_h)."""
    rng = np.random.default_rng(1)
    errors = [(int(r), int(c), int(o)) for r, c, o in zip(rng.integers(2, 30, 12), rng.integers(2, 62, 12),
                                                          rng.choice([-5, -1, 1, 2, 7], 12))]
    psi_h, coarse, label = _ramp(errors=errors)
    torch.manual_seed(0)
    model = build_model("dptpu", TINY_DPTPU).eval()
    with torch.no_grad():
        model.head_gate.bias.fill_(1.0 / GATE_GAIN)
        out = model(psi_h, psi_h * 0 + 1.0, coarse, torch.tensor([64.0]))[0, 0].numpy()
    assert np.mean(coarse[0, 0].numpy() == label) < 0.995
    assert np.array_equal(np.rint(out), label)


def test_default_config_is_small_enough_for_cpu_training():
    parameters = sum(p.numel() for p in DPTPUNet().parameters())
    assert parameters == 36_777  # widths 8/16/24/32, decoder 8 (docs/network.md)


def test_bad_config_names_the_field():
    with pytest.raises(ValueError, match="multiple of heads"):
        build_model("dptpu", {**TINY_DPTPU, "heads": [3, 1, 1, 1]})
    with pytest.raises(ValueError, match="unknown DP-TPU config keys \\['depth'\\]"):
        DPTPUConfig.from_dict({"depth": [1, 1, 1, 1]})
    with pytest.raises(ValueError, match="model kind must be one of dptpu, unet"):
        build_model("resnet")
    with pytest.raises(ValueError, match="config of architecture 1 \\(it has stem_width\\).*retrain"):
        build_model("dptpu", {"widths": [16, 32, 48, 64], "stem_width": 8})
    with pytest.raises(ValueError, match="reductions must be 3 integers >= 1"):
        DPTPUConfig(reductions=(8, 4))
