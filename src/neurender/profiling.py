"""Where a job's time goes: a job run under cProfile when ``NEURENDER_PROFILE`` names a
folder, and a profile summed into stages (reading data, training steps and their forward,
backward and optimiser parts, validation, export, checkpoints, TensorBoard).

Profile every job of a run (its stats land beside the logs' layout)::

    NEURENDER_PROFILE=results/profiles snakemake --cores 2 results/report.html

and sum them with ``benchmarks/job_stages.py``. cProfile costs some speed in Python-heavy
code; the stages' shares, not the profiled run's wall time, are what it is for.
"""

from __future__ import annotations

import cProfile
import os
import pstats
from collections.abc import Callable
from pathlib import Path

import pandas as pd

from neurender import io

#: Environment variable naming the folder the jobs' profiles are written to.
PROFILE_ENV = "NEURENDER_PROFILE"

#: A function in a profile: ``(file name, line, function name)``, as :mod:`pstats` keys it.
Function = tuple[str, int, str]

#: Stages by what they time, each the cumulative seconds of the functions matching a
#: ``(file-name suffix, function name)`` pair, of their calls from ``caller`` only when one
#: is named (a backward pass, a batch: those of the training loop). Stages ``part_of``
#: another are parts of it; the others do not overlap in the jobs of this project.
STAGES = pd.DataFrame(
    [
        ("training steps", "", "neurender/train.py", "train_epoch", ""),
        ("backward", "training steps", "torch/_tensor.py", "backward", "train_epoch"),
        ("batches", "training steps", "torch/utils/data/dataloader.py", "__next__", "train_epoch"),
        ("optimiser step", "training steps", "torch/optim/adam.py", "step", ""),
        ("validation", "", "neurender/train.py", "validate", ""),
        ("reading data", "", "neurender/io.py", "read_exr", ""),
        ("reading data", "", "neurender/io.py", "read_png", ""),
        ("reading data", "", "neurender/io.py", "load_npz", ""),
        ("input checksum", "", "neurender/io.py", "checksum", ""),
        ("optimiser set-up", "", "neurender/train.py", "_start", ""),
        ("checkpoints", "", "neurender/train.py", "_atomic_torch_save", ""),
        ("export", "", "neurender/nn/inference.py", "export_onnx", ""),
        ("export", "", "neurender/nn/inference.py", "quantize_convolutions", ""),
        ("TensorBoard", "", "neurender/tensorboard_log.py", "epoch", ""),
        ("TensorBoard", "", "neurender/tensorboard_log.py", "close", ""),
    ],
    columns=["stage", "part_of", "file", "function", "caller"],
)


def profile_file(log_file: str | Path, folder: str | Path) -> Path:
    """Where the profile of the job logging to ``log_file`` goes under ``folder``: the
    log's last two parts (rule, job), suffix ``.pstats``."""
    log = Path(log_file)
    return Path(folder) / log.parent.name / log.with_suffix(".pstats").name


def run_profiled(call: Callable[[], None], log_file: str | Path) -> None:
    """``call()``; under cProfile, its stats written (atomically) to
    :func:`profile_file` when ``NEURENDER_PROFILE`` is set, whether or not it raises."""
    folder = os.environ.get(PROFILE_ENV)
    if not folder:
        call()
        return
    profiler = cProfile.Profile()
    try:
        profiler.runcall(call)
    finally:
        with io.atomic_path(profile_file(log_file, folder)) as tmp:
            profiler.dump_stats(str(tmp))


def _matches(function: Function, file: str, name: str) -> bool:
    return function[0].replace("\\", "/").endswith(file) and function[2] == name


def stage_seconds(stats: pstats.Stats) -> pd.DataFrame:
    """Seconds of each stage of :data:`STAGES` in ``stats`` and the profile's total:
    columns ``stage, part_of, seconds``; one row per stage (its matches summed), then
    ``"forward and loss"`` (the training steps less their other parts), ``"other"`` (the
    total less the stages that are part of none) and ``"total"`` (the profile's longest
    cumulative time: the job's call)."""
    table = stats.stats  # type: ignore[attr-defined]  # {function: (cc, nc, tt, ct, callers)}
    total = max((entry[3] for entry in table.values()), default=0.0)
    seconds: dict[tuple[str, str], float] = {}
    for row in STAGES.itertuples():
        value = 0.0
        for function, (_, _, _, cumulative, callers) in table.items():
            if not _matches(function, row.file, row.function):
                continue
            if row.caller:
                value += sum(c[3] for f, c in callers.items() if f[2] == row.caller)
            else:
                value += cumulative
        key = (row.stage, row.part_of)
        seconds[key] = seconds.get(key, 0.0) + value
    frame = pd.DataFrame(
        [(stage, part_of, s) for (stage, part_of), s in seconds.items()],
        columns=["stage", "part_of", "seconds"],
    )
    steps = frame.loc[frame.stage == "training steps", "seconds"].sum()
    parts = frame.loc[frame.part_of == "training steps", "seconds"].sum()
    top = frame.loc[frame.part_of == "", "seconds"].sum()
    extra = [
        ("forward and loss", "training steps", max(steps - parts, 0.0)),
        ("other", "", max(total - top, 0.0)),
        ("total", "", total),
    ]
    return pd.concat([frame, pd.DataFrame(extra, columns=frame.columns)], ignore_index=True)
