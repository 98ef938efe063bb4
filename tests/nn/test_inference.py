import numpy as np
import pytest
import torch
from torch import nn

from neurender.nn.inference import (
    OnnxNetwork,
    export_onnx,
    fold_batch_norms,
    prepare_for_inference,
)
from neurender.nn.unet import ResUNet


def _trained_looking_unet() -> ResUNet:
    """A U-Net whose batch norms hold non-trivial running statistics and affine terms."""
    torch.manual_seed(0)
    model = ResUNet(6, 5, [8, 16], blocks=1)
    model.train()
    with torch.no_grad():
        for bn in (m for m in model.modules() if isinstance(m, nn.BatchNorm2d)):
            bn.weight.uniform_(0.5, 2.0)
            bn.bias.uniform_(-0.5, 0.5)
        for _ in range(3):
            model(torch.randn(4, 6, 16, 16) * 2 + 0.5)
    return model.eval()


def test_prepared_network_computes_the_eager_network():
    model = _trained_looking_unet()
    x = torch.randn(3, 6, 16, 16)
    with torch.no_grad():
        expected = model(x)
        fast = prepare_for_inference(model)
        for layout in (torch.contiguous_format, torch.channels_last):
            torch.testing.assert_close(
                fast(x.to(memory_format=layout)), expected, atol=1e-5, rtol=1e-4
            )


def test_every_batch_norm_is_folded_and_the_original_is_untouched():
    model = _trained_looking_unet()
    n_bn = sum(isinstance(m, nn.BatchNorm2d) for m in model.modules())
    folded = fold_batch_norms(model)
    assert n_bn > 0
    assert not any(isinstance(m, nn.BatchNorm2d) for m in folded.modules())
    assert sum(isinstance(m, nn.BatchNorm2d) for m in model.modules()) == n_bn
    assert next(prepare_for_inference(model).stem[0].parameters()).is_contiguous(
        memory_format=torch.channels_last
    )


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    model = _trained_looking_unet()
    path = tmp_path_factory.mktemp("onnx") / "unet.onnx"
    export_onnx(model, torch.randn(2, 6, 16, 16), path)
    return model, path


@pytest.mark.parametrize("batch", [1, 3])
def test_onnx_runtime_computes_the_pytorch_network_at_any_batch_size(exported, batch):
    model, path = exported
    x = torch.randn(batch, 6, 16, 16)
    with torch.no_grad():
        expected = model(x).numpy()
    np.testing.assert_allclose(OnnxNetwork(path, threads=2)(x.numpy()), expected, atol=1e-5)


def test_exported_file_is_self_contained(exported):
    _, path = exported
    assert sorted(p.name for p in path.parent.iterdir()) == ["unet.onnx"]  # no external data


def test_export_refuses_a_batch_of_one_and_a_failed_check_leaves_nothing(tmp_path):
    model = _trained_looking_unet()
    with pytest.raises(ValueError, match="B >= 2"):
        export_onnx(model, torch.randn(1, 6, 16, 16), tmp_path / "a.onnx")
    with pytest.raises(ValueError, match="differs from PyTorch"):
        export_onnx(model, torch.randn(2, 6, 16, 16), tmp_path / "b.onnx", atol=-1.0)
    assert list(tmp_path.iterdir()) == []


def test_missing_onnx_file_is_named(tmp_path):
    with pytest.raises(FileNotFoundError, match="nope.onnx"):
        OnnxNetwork(tmp_path / "nope.onnx")


class _Radiance(nn.Module):
    """A network whose outputs are large, as linear HDR radiance is."""

    def __init__(self, model: nn.Module, scale: float):
        super().__init__()
        self.model, self.scale = model, scale

    def forward(self, x):
        return self.model(x) * self.scale


def test_the_export_check_scales_with_the_outputs_magnitude(tmp_path):
    model = _Radiance(_trained_looking_unet(), 1e6)
    x = torch.randn(2, 6, 16, 16)
    with torch.inference_mode():
        peak = float(model(x).abs().max())
    # float32 rounding of outputs near 1e6 is far above an absolute 1e-3 ...
    with pytest.raises(ValueError, match=r"differs from PyTorch .*rtol 0.0 x max\|y\|"):
        export_onnx(model, x, tmp_path / "absolute.onnx", atol=1e-3)
    # ... and within a relative 1e-4 of the largest output.
    error = export_onnx(model, x, tmp_path / "relative.onnx", atol=0.0, rtol=1e-4)
    assert 0 < error <= 1e-4 * peak


class _IgnoresItsMiddleInput(nn.Module):
    def forward(self, a: torch.Tensor, unused: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
        return a * 2 + b


def test_an_input_the_graph_ignores_stays_an_input_in_its_place(tmp_path):
    """The exporter prunes inputs a graph does not read; the file still takes all three in
    order (batch axis dynamic) and computes the module's output."""
    examples = (torch.rand(2, 3), torch.rand(2, 5), torch.rand(2, 3))
    path = tmp_path / "m.onnx"
    export_onnx(_IgnoresItsMiddleInput(), examples, path, input_names=("a", "unused", "b"))
    network = OnnxNetwork(path)
    assert network.inputs == ["a", "unused", "b"]
    x = [np.random.default_rng(0).random((4, n), dtype=np.float32) for n in (3, 5, 3)]
    np.testing.assert_allclose(network(*x), x[0] * 2 + x[2], rtol=1e-6)
