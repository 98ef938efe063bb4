import itertools

import numpy as np
import pytest
import torch
from torch import nn

from neurender.nn.inference import (
    OnnxNetwork,
    channel_average_convolutions,
    export_onnx,
    fold_batch_norms,
    least_loaded_milliseconds,
    part_rows,
    prepare_for_inference,
    quantize_convolutions,
)
from neurender.nn.norms import PixelNorm
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


def _int8_unet(tmp_path, exported, calibration_batches=16):
    """The exported U-Net quantized on random batches like the inputs it is tested on."""
    _, path = exported
    rng = np.random.default_rng(1)
    feeds = [
        {"x": rng.standard_normal((2, 6, 16, 16), np.float32)} for _ in range(calibration_batches)
    ]
    target = tmp_path / "unet.int8.onnx"
    quantize_convolutions(path, target, feeds)
    return target


def test_int8_graph_has_int8_weights_and_stays_close_to_the_float_graph(exported, tmp_path):
    import onnx

    model, path = exported
    target = _int8_unet(tmp_path, exported)
    graph = onnx.load(str(target)).graph
    convolutions = sum(n.op_type == "Conv" for n in onnx.load(str(path)).graph.node)
    int8 = [i for i in graph.initializer if i.data_type == onnx.TensorProto.INT8]
    kernels = [i for i in int8 if len(i.dims) == 4]  # zero points are int8 vectors
    assert convolutions > 0 and len(kernels) == convolutions  # one per convolution
    x = np.random.default_rng(2).standard_normal((3, 6, 16, 16), np.float32)
    with torch.no_grad():
        expected = model(torch.from_numpy(x)).numpy()
    got = OnnxNetwork(target)(x)
    # An approximation, and a close one: on average within one uint8 step of the output range
    # (errors add up over the U-Net's eleven layers; the largest where an input lies beyond
    # the calibrated range and is clipped).
    span = expected.max() - expected.min()
    error = np.abs(got - expected)
    assert 0 < error.max() <= 0.04 * span
    assert error.mean() <= span / 255


def test_int8_needs_calibration_and_leaves_only_its_file(exported, tmp_path, monkeypatch):
    _, path = exported
    monkeypatch.chdir(tmp_path)  # the quantizer's helpers write scratch files here
    with pytest.raises(ValueError, match="unet.onnx.*no calibration"):
        quantize_convolutions(path, tmp_path / "none.onnx", [])
    _int8_unet(tmp_path, exported)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["unet.int8.onnx"]


def test_int8_keeps_the_channel_averages_float_and_quantizes_the_learnt_kernels(tmp_path):
    import onnx

    torch.manual_seed(0)
    model = nn.Sequential(nn.Conv2d(3, 8, 3, padding=1), PixelNorm(8), nn.Conv2d(8, 2, 1))
    with torch.no_grad():
        # A 1x1 learnt kernel of equal weights is not an average: it has a bias.
        model[2].weight.fill_(0.25)
    path = tmp_path / "norm.onnx"
    export_onnx(prepare_for_inference(model), torch.randn(2, 3, 8, 8), path)
    nodes = onnx.load(str(path)).graph.node
    averages = channel_average_convolutions(onnx.load(str(path)))
    # PixelNorm's mean of squares alone: its channel mean is folded into the first kernel.
    assert len(averages) == 1 and sum(n.op_type == "Conv" for n in nodes) == 3
    rng = np.random.default_rng(0)
    feeds = [{"x": rng.standard_normal((1, 3, 8, 8), np.float32)} for _ in range(8)]
    target = tmp_path / "norm.int8.onnx"
    quantize_convolutions(path, target, feeds)
    graph = onnx.load(str(target)).graph
    kernels = [
        i for i in graph.initializer if i.data_type == onnx.TensorProto.INT8 and len(i.dims) == 4
    ]
    assert sorted(tuple(k.dims) for k in kernels) == [(2, 8, 1, 1), (8, 3, 3, 3)]
    average = next(n for n in graph.node if n.name == averages[0])
    producers = {o: n.op_type for n in graph.node for o in n.output}
    assert producers[average.input[0]] != "DequantizeLinear"  # float32 in, not int8


def test_least_loaded_milliseconds_keeps_each_engines_fastest_round(monkeypatch):
    """Parts are timed in turn, round after round; each engine keeps its minimum over the
    rounds, which for a part may come from different rounds for the two engines."""
    calls = []
    times = itertools.cycle(
        [
            {"pytorch": 5.0, "onnxruntime": 2.0},  # a, round 1
            {"pytorch": 9.0, "onnxruntime": 9.0},  # b, round 1
            {"pytorch": 3.0, "onnxruntime": 4.0},  # a, round 2
            {"pytorch": 8.0, "onnxruntime": 7.0},  # b, round 2
        ]
    )

    def fake(module, onnx_file, inputs, threads):
        calls.append((onnx_file, threads))
        return next(times)

    monkeypatch.setattr("neurender.nn.inference.engine_milliseconds", fake)
    parts = {"a": (nn.Identity(), "a.onnx", ()), "b": (nn.Identity(), "b.onnx", ())}
    best = least_loaded_milliseconds(parts, threads=2, rounds=2)
    assert calls == [("a.onnx", 2), ("b.onnx", 2)] * 2  # in turn, round after round
    assert best == {
        "a": {"pytorch": 3.0, "onnxruntime": 2.0},
        "b": {"pytorch": 8.0, "onnxruntime": 7.0},
    }


def test_part_rows_name_each_part_its_times_check_and_file_size(monkeypatch, tmp_path):
    monkeypatch.setattr(
        "neurender.nn.inference.engine_milliseconds",
        lambda module, onnx_file, inputs, threads: {"pytorch": 3.0, "onnxruntime": 1.5},
    )
    graph = tmp_path / "g.onnx"
    graph.write_bytes(b"x" * 17)
    (row,) = part_rows({"g": (nn.Identity(), graph, ())}, {"g": 1e-6}, threads=2, rounds=2)
    assert row["part"] == "g" and row["threads"] == 2 and row["onnx_bytes"] == 17
    assert (row["onnxruntime_ms"], row["pytorch_ms"], row["max_abs_diff_vs_pytorch"]) == (
        1.5,
        3.0,
        1e-6,
    )
    assert "2 threads" in row["hardware"]
