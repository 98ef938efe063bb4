"""DeepPRT's deployment rows: the evaluation's own times of each network beside its file."""

import math

import numpy as np
import pytest

from neurender.nn.inference import onnx_metadata
from neurender.prt.equal_quality import deployment_rows, inference_seconds
from neurender.prt.frames import Split
from neurender.prt.model import DeepPRT, export_deepprt
from neurender.prt.training import train_deepprt


@pytest.fixture(scope="module")
def shipped(tmp_path_factory):
    """A diffuse network trained for one epoch on 8 x 8 frames, and its ONNX file."""
    tmp = tmp_path_factory.mktemp("deepprt")
    rng = np.random.default_rng(3)

    def split(frames):
        shape = (frames, 8, 8)
        return Split(
            rng.normal(size=(*shape, 3)).astype(np.float32),
            rng.normal(size=(*shape, 3)).astype(np.float32),
            rng.uniform(0, 1, (*shape, 16)).astype(np.float32),
            rng.uniform(0, 1, (*shape, 3, 16)).astype(np.float32),
            rng.uniform(0, 1, (frames, 2)),
        )

    train, val = split(4), split(2)
    cfg = {"seed": 0, "widths": [4, 8], "blocks": 1, "epochs": 1, "batch_size": 2}
    cfg |= {"lr": 1e-3, "lr_schedule": "cosine", "residual_targets": True, "device": "cpu"}
    checkpoint, onnx_file = tmp / "net.pt", tmp / "net.onnx"
    train_deepprt(train, val, "diffuse", cfg, 1, str(checkpoint), str(tmp / "loss.csv"))
    export_deepprt(checkpoint, val, onnx_file)
    return checkpoint, str(onnx_file), val


def test_a_row_per_network_with_the_times_it_was_given(shipped):
    checkpoint, onnx_file, test = shipped
    net = DeepPRT(checkpoint, onnx_file, device="cpu")
    seconds = inference_seconds(net, test)
    assert set(seconds) == {"onnxruntime", "pytorch"} and min(seconds.values()) > 0
    (row,) = deployment_rows(
        "head", {"diffuse": net}, {"diffuse": onnx_file}, {"diffuse": seconds}, test, 1
    )
    assert (row["method"], row["network"], row["resolution"]) == ("prt", "head diffuse", "8x8")
    assert row["parameters"] == net.parameters and row["onnx_file"] == onnx_file
    with open(onnx_file, "rb") as f:
        assert row["onnx_bytes"] == len(f.read())
    stored = onnx_metadata(onnx_file)["neurender.max_abs_diff_vs_pytorch"]
    assert row["max_abs_diff_vs_pytorch"] == float(stored) <= 1e-4
    assert row["onnxruntime_ms_per_frame"] == 1000 * seconds["onnxruntime"]
    assert row["pytorch_ms_per_frame"] == 1000 * seconds["pytorch"]
    assert row["threads"] == 1 and row["hardware"].endswith("1 thread")


def test_a_network_run_by_pytorch_alone_has_no_onnx_runtime_time(shipped):
    checkpoint, onnx_file, test = shipped
    net = DeepPRT(checkpoint, device="cpu")  # as on a GPU: PyTorch is the only engine
    (row,) = deployment_rows(
        "head", {"diffuse": net}, {"diffuse": onnx_file}, {"diffuse": {"pytorch": 0.002}}, test, 1
    )
    assert math.isnan(row["onnxruntime_ms_per_frame"]) and row["pytorch_ms_per_frame"] == 2.0
