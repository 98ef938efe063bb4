"""The deployment table: every trained network as the file a renderer ships, and its cost.

Each method writes ``results/<method>/deployment.csv``, one row per network with the
columns of :data:`COLUMNS`: its ONNX file (the network with its normalisation, checked
against PyTorch before it was written: :func:`neurender.nn.inference.export_onnx`), the
input resolution it was exported and timed at (the config's), its parameters, the file's
size, the largest |ONNX Runtime - PyTorch| of that check, and the median milliseconds of
one frame (batch one) by ONNX Runtime and by PyTorch with the same ``threads``
(:func:`neurender.nn.inference.engine_milliseconds`), and the hardware they ran on
(:func:`neurender.timing.hardware`). A time that was not measured (ONNX Runtime where a
network ran on a GPU) is NaN.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import pandas as pd

from neurender import io
from neurender.nn.inference import onnx_metadata

COLUMNS = (
    "method",
    "network",
    "resolution",
    "parameters",
    "onnx_file",
    "onnx_bytes",
    "max_abs_diff_vs_pytorch",
    "onnxruntime_ms_per_frame",
    "pytorch_ms_per_frame",
    "threads",
    "hardware",
)


def onnx_file_facts(path: str | Path) -> dict[str, float]:
    """``onnx_bytes`` and ``max_abs_diff_vs_pytorch`` (the export's check, stored in the
    file's metadata) of an ONNX file written by :func:`neurender.nn.inference.export_onnx`."""
    key = "neurender.max_abs_diff_vs_pytorch"
    metadata = onnx_metadata(path)
    if key not in metadata:
        raise ValueError(f"ONNX file {path} has no {key} metadata: export it with export_onnx")
    size = Path(path).stat().st_size
    return {"onnx_bytes": size, "max_abs_diff_vs_pytorch": float(metadata[key])}


def deployment_row(
    method: str,
    network: str,
    onnx_file: str | Path,
    size: tuple[int, int],
    measured: Mapping[str, float],
    threads: int,
    hardware: str,
) -> dict:
    """One row of the table (:data:`COLUMNS`).

    Args:
        size: the input's ``(height, width)`` in pixels.
        measured: ``parameters``, ``onnx_bytes``, ``max_abs_diff_vs_pytorch``,
            ``ms_per_frame_onnxruntime``, ``ms_per_frame_pytorch`` (as
            :func:`neurender.ndr.deploy.export_variant` returns them).
    """
    return {
        "method": method,
        "network": network,
        "resolution": f"{size[1]}x{size[0]}",
        "parameters": int(measured["parameters"]),
        "onnx_file": str(onnx_file),
        "onnx_bytes": int(measured["onnx_bytes"]),
        "max_abs_diff_vs_pytorch": float(measured["max_abs_diff_vs_pytorch"]),
        "onnxruntime_ms_per_frame": float(measured["ms_per_frame_onnxruntime"]),
        "pytorch_ms_per_frame": float(measured["ms_per_frame_pytorch"]),
        "threads": int(threads),
        "hardware": hardware,
    }


def deployment_table(rows: list[dict]) -> pd.DataFrame:
    """The rows as a table with exactly :data:`COLUMNS` (a row missing one is an error)."""
    frame = pd.DataFrame(rows, columns=list(COLUMNS))
    if frame.isna()[["method", "network", "onnx_file", "hardware"]].any().any():
        raise ValueError("deployment rows need a method, network, ONNX file and hardware")
    return frame


def read_deployment(path: str | Path) -> pd.DataFrame:
    """A ``deployment.csv`` (its columns checked, the file named in an error)."""
    return io.read_csv(path, COLUMNS)
