"""The deployment table: every trained network as the file a renderer ships, and its cost.

Each method writes ``results/<method>/deployment.csv``, one row per network with the
columns of :data:`COLUMNS`: its ONNX file (the network with its normalisation, checked
against PyTorch before it was written: :func:`neurender.nn.inference.export_onnx`), the
input resolution it was exported and timed at (the config's), its parameters, the file's
size, the largest |ONNX Runtime - PyTorch| of that check, and the median milliseconds of
one frame (batch one) by ONNX Runtime and by PyTorch with the same ``threads``, and the
hardware they ran on (:func:`neurender.timing.hardware`). A time that was not measured
(ONNX Runtime where a network ran on a GPU) is NaN.

:func:`measure` is the whole measurement of a network exported at deployment (export,
check, both engines timed, one row: metaballs, NDR); :func:`deployment_row` the row of a
network exported and timed elsewhere (DeepPRT exports when it trains and times its whole
prediction, inputs and decoding included, by each engine it holds).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

import pandas as pd

from neurender import io

if TYPE_CHECKING:
    import torch
    from torch import nn

#: The engines timed, by the column of their milliseconds per frame.
ENGINE_COLUMNS = {
    "onnxruntime": "onnxruntime_ms_per_frame",
    "pytorch": "pytorch_ms_per_frame",
}
#: The engines' names as tables show them.
ENGINE_NAMES = {"onnxruntime": "ONNX Runtime", "pytorch": "PyTorch"}
COLUMNS = (
    "method",
    "network",
    "resolution",
    "parameters",
    "onnx_file",
    "onnx_bytes",
    "max_abs_diff_vs_pytorch",
    *ENGINE_COLUMNS.values(),
    "threads",
    "hardware",
)


#: The metadata keys of a shipped graph (:func:`measure`) that name what it is.
METHOD_KEY, NETWORK_KEY = "neurender.method", "neurender.network"


def shipped_network(path: str | Path) -> tuple[str, str]:
    """The method and network a shipped graph (written by :func:`measure`) says it is;
    ``ValueError`` naming the file when it does not say."""
    from neurender.nn.inference import onnx_metadata

    metadata = onnx_metadata(path)
    if METHOD_KEY not in metadata or NETWORK_KEY not in metadata:
        raise ValueError(
            f"ONNX file {path} names no {METHOD_KEY} and {NETWORK_KEY} in its metadata: "
            "expected a graph shipped by neurender.deployment.measure (rerun its deploy rule)"
        )
    return metadata[METHOD_KEY], metadata[NETWORK_KEY]


def onnx_check_error(path: str | Path) -> float:
    """The largest |ONNX Runtime - PyTorch| of the export's check, stored in the metadata
    of an ONNX file written by :func:`neurender.nn.inference.export_onnx`."""
    from neurender.nn.inference import onnx_metadata

    key = "neurender.max_abs_diff_vs_pytorch"
    metadata = onnx_metadata(path)
    if key not in metadata:
        raise ValueError(f"ONNX file {path} has no {key} metadata: export it with export_onnx")
    return float(metadata[key])


def deployment_row(
    method: str,
    network: str,
    onnx_file: str | Path,
    size: tuple[int, int],
    parameters: int,
    max_abs_diff: float,
    milliseconds: Mapping[str, float],
    threads: int,
    machine: str,
) -> dict:
    """One row of the table (:data:`COLUMNS`); ``onnx_bytes`` is the file's size.

    Args:
        size: the input's ``(height, width)`` in pixels.
        max_abs_diff: the export check's largest |ONNX Runtime - PyTorch|.
        milliseconds: median milliseconds of one frame by engine (the keys of
            :data:`ENGINE_COLUMNS`); an engine not timed is NaN.
        machine: the ``hardware`` column, where the times were measured
            (:func:`neurender.timing.hardware`).
    """
    unknown = sorted(set(milliseconds) - set(ENGINE_COLUMNS))
    if unknown:
        raise KeyError(
            f"{network}: times of unknown engines {unknown}; expected {list(ENGINE_COLUMNS)}"
        )
    times = {c: float(milliseconds.get(e, math.nan)) for e, c in ENGINE_COLUMNS.items()}
    return {
        "method": method,
        "network": network,
        "resolution": f"{size[1]}x{size[0]}",
        "parameters": int(parameters),
        "onnx_file": str(onnx_file),
        "onnx_bytes": Path(onnx_file).stat().st_size,
        "max_abs_diff_vs_pytorch": float(max_abs_diff),
        **times,
        "threads": int(threads),
        "hardware": machine,
    }


def measure(
    method: str,
    network: str,
    graph: nn.Module,
    examples: tuple[torch.Tensor, ...],
    onnx_out: str | Path,
    threads: int,
    *,
    atol: float,
    rtol: float = 0.0,
    input_names: tuple[str, ...] = ("x",),
) -> dict:
    """The deployment row of ``graph`` (an eval-mode CPU module: the trained network with
    its normalisation): exported to ``onnx_out`` and checked on ``examples`` (each input
    ``(B >= 2, C, H, W)``, named ``input_names``; allowed difference ``atol + rtol *
    max|y|``, :func:`neurender.nn.inference.export_onnx`), then both engines timed on the
    first example on the CPU with ``threads`` threads. The file names its ``method`` and
    ``network`` in its metadata (:func:`shipped_network`)."""
    # torch here, so that the jobs that only read or write the table never load it
    from neurender.nn.inference import engine_milliseconds, export_onnx
    from neurender.nn.unet import count_parameters
    from neurender.timing import hardware

    names = {METHOD_KEY: method, NETWORK_KEY: network}
    error = export_onnx(
        graph, examples, onnx_out, atol=atol, input_names=input_names, rtol=rtol, metadata=names
    )
    ms = engine_milliseconds(graph, onnx_out, tuple(x[:1] for x in examples), threads)
    size = tuple(examples[0].shape[-2:])
    where = hardware(threads, "cpu")
    parameters = count_parameters(graph)
    return deployment_row(method, network, onnx_out, size, parameters, error, ms, threads, where)


def deployment_table(rows: list[dict]) -> pd.DataFrame:
    """The rows as a table with exactly :data:`COLUMNS` (a row missing one is an error)."""
    frame = pd.DataFrame(rows, columns=list(COLUMNS))
    if frame.isna()[["method", "network", "onnx_file", "hardware"]].any().any():
        raise ValueError("deployment rows need a method, network, ONNX file and hardware")
    return frame


def read_deployment(path: str | Path) -> pd.DataFrame:
    """A ``deployment.csv`` (its columns checked, the file named in an error)."""
    return io.read_csv(path, COLUMNS)
