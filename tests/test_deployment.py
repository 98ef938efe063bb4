import onnx
import pandas as pd
import pytest
from onnx import TensorProto, helper

from neurender import io
from neurender.deployment import (
    COLUMNS,
    deployment_row,
    deployment_table,
    onnx_file_facts,
    read_deployment,
)

MEASURED = {
    "parameters": 10,
    "onnx_bytes": 100,
    "max_abs_diff_vs_pytorch": 1e-7,
    "ms_per_frame_onnxruntime": 0.5,
    "ms_per_frame_pytorch": 1.5,
}


def test_a_row_states_resolution_as_width_x_height():
    row = deployment_row("ndr", "ndr", "a.onnx", (32, 64), MEASURED, 2, "CPU, 2 threads")
    assert list(row) == list(COLUMNS)
    assert row["resolution"] == "64x32" and row["pytorch_ms_per_frame"] == 1.5


def test_a_table_round_trips_and_a_file_missing_columns_is_named(tmp_path):
    rows = [deployment_row("prt", "head diffuse", "a.onnx", (8, 8), MEASURED, 1, "CPU, 1 thread")]
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
        onnx_file_facts(tmp_path / "unchecked.onnx")
