import math

import onnx
import pandas as pd
import pytest
import torch
from onnx import TensorProto, helper

from neurender import io
from neurender.deployment import (
    COLUMNS,
    deployment_row,
    deployment_table,
    measure,
    onnx_check_error,
    read_deployment,
    shipped_network,
)
from neurender.nn.inference import OnnxNetwork, onnx_metadata

TIMES = {"onnxruntime": 0.5, "pytorch": 1.5}


@pytest.fixture
def onnx_file(tmp_path):
    path = tmp_path / "a.onnx"
    path.write_bytes(bytes(100))
    return path


def test_a_row_states_resolution_as_width_x_height_and_the_files_size(onnx_file):
    row = deployment_row("ndr", "ndr", onnx_file, (32, 64), 10, 1e-7, TIMES, 2, "CPU, 2 threads")
    assert list(row) == list(COLUMNS)
    assert row["resolution"] == "64x32" and row["onnx_bytes"] == 100
    assert (row["onnxruntime_ms_per_frame"], row["pytorch_ms_per_frame"]) == (0.5, 1.5)


def test_an_engine_not_timed_is_nan_and_an_unknown_one_is_refused(onnx_file):
    row = deployment_row("prt", "x", onnx_file, (8, 8), 1, 0.0, {"pytorch": 2.0}, 1, "GPU")
    assert math.isnan(row["onnxruntime_ms_per_frame"]) and row["pytorch_ms_per_frame"] == 2.0
    with pytest.raises(KeyError, match="tensorrt"):
        deployment_row("prt", "x", onnx_file, (8, 8), 1, 0.0, {"tensorrt": 1.0}, 1, "GPU")


def test_a_table_round_trips_and_a_file_missing_columns_is_named(tmp_path, onnx_file):
    rows = [deployment_row("prt", "head diffuse", onnx_file, (8, 8), 10, 0.0, TIMES, 1, "CPU")]
    io.write_csv(tmp_path / "deployment.csv", deployment_table(rows))
    assert read_deployment(tmp_path / "deployment.csv").network.tolist() == ["head diffuse"]
    io.write_csv(tmp_path / "bad.csv", pd.DataFrame({"network": ["x"]}))
    with pytest.raises(ValueError, match="bad.csv"):
        read_deployment(tmp_path / "bad.csv")


def test_a_file_that_export_onnx_did_not_check_is_refused(tmp_path):
    node = helper.make_node("Identity", ["x"], ["y"])
    value = helper.make_tensor_value_info
    graph = helper.make_graph(
        [node], "g", [value("x", TensorProto.FLOAT, [1])], [value("y", TensorProto.FLOAT, [1])]
    )
    onnx.save(helper.make_model(graph), tmp_path / "unchecked.onnx")
    with pytest.raises(ValueError, match="unchecked.onnx"):
        onnx_check_error(tmp_path / "unchecked.onnx")
    with pytest.raises(ValueError, match=r"unchecked.onnx names no neurender.method"):
        shipped_network(tmp_path / "unchecked.onnx")


def test_measure_exports_a_checked_file_and_times_both_engines(tmp_path):
    torch.manual_seed(0)
    graph = torch.nn.Sequential(torch.nn.Conv2d(3, 4, 3, padding=1), torch.nn.ReLU()).eval()
    x = torch.rand(2, 3, 6, 10)
    out = tmp_path / "net.onnx"
    row = measure("toy", "conv", graph, (x,), out, 1, atol=1e-5)
    assert list(row) == list(COLUMNS) and (row["method"], row["network"]) == ("toy", "conv")
    assert row["resolution"] == "10x6" and row["parameters"] == 3 * 4 * 9 + 4
    assert row["onnx_bytes"] == out.stat().st_size and row["onnx_file"] == str(out)
    assert shipped_network(out) == ("toy", "conv")
    stored = float(onnx_metadata(out)["neurender.max_abs_diff_vs_pytorch"])
    assert row["max_abs_diff_vs_pytorch"] == pytest.approx(stored, rel=1e-2, abs=1e-12)
    assert row["onnxruntime_ms_per_frame"] > 0 and row["pytorch_ms_per_frame"] > 0
    assert row["threads"] == 1 and row["hardware"].endswith("1 thread")
    with torch.no_grad():
        expected = graph(x).numpy()
    torch.testing.assert_close(
        torch.from_numpy(OnnxNetwork(out)(x.numpy())), torch.from_numpy(expected), atol=1e-5, rtol=0
    )
