"""DP-TPU and U-Net architectures: output shapes for odd input sizes, the residual start, config checks."""
import pytest
import torch

from dptpu.models.factory import build_model
from dptpu.models.network import DPTPUConfig, DPTPUNet, median3x3, network_inputs
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


def test_inputs_are_scaled_to_unit_range_and_flag_an_order_off_its_neighbours():
    high = torch.full((1, 1, 5, 5), torch.pi)
    low = torch.full((1, 1, 5, 5), torch.pi / 2)
    coarse = torch.full((1, 1, 5, 5), 16.0)
    coarse[0, 0, 2, 2] = 17.0  # one order off
    coarse[0, 0, 0, 4] = 40.0  # far off: clipped
    x = network_inputs(high, low, coarse, torch.tensor([64.0]))
    assert torch.allclose(x[0, :, 4, 0], torch.tensor([0.5, 0.25, 0.25, 0.0]))
    assert float(x[0, 3, 2, 2]) == pytest.approx(1.0) and float(x[0, 3, 0, 4]) == pytest.approx(4.0)
    assert float(x[0, 2, 2, 2]) == pytest.approx(17.0 / 64.0)


def test_median3x3_is_the_median_of_each_window():
    x = torch.arange(20, dtype=torch.float32).reshape(1, 1, 4, 5) ** 2 % 11
    got = median3x3(x)[0, 0]
    padded = torch.nn.functional.pad(x, (1, 1, 1, 1), mode="replicate")[0, 0]
    expected = torch.tensor([[float(padded[r:r + 3, c:c + 3].flatten().sort().values[4]) for c in range(5)]
                             for r in range(4)])
    assert torch.equal(got, expected)


def test_default_config_is_small_enough_for_cpu_training():
    parameters = sum(p.numel() for p in DPTPUNet().parameters())
    assert 50_000 < parameters < 500_000


def test_bad_config_names_the_field():
    with pytest.raises(ValueError, match="multiple of heads"):
        build_model("dptpu", {**TINY_DPTPU, "heads": [3, 1, 1, 1]})
    with pytest.raises(ValueError, match="unknown DP-TPU config keys \\['depth'\\]"):
        DPTPUConfig.from_dict({"depth": [1, 1, 1, 1]})
    with pytest.raises(ValueError, match="model kind must be one of dptpu, unet"):
        build_model("resnet")
