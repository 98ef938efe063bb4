"""What TensorBoard logging (neurender.tensorboard_log) adds to a training run.

python benchmarks/tensorboard_overhead.py benchmarks/results/tensorboard_overhead.csv

Per case, one training with event files: the seconds spent in the logger per epoch
(scalars, previews and their forward pass, flush) and once per run (opening the writer,
closing it), against the epoch's own seconds; and once per job, importing
``torch.utils.tensorboard`` in a fresh interpreter. Cases: the tests' toy images, the
smoke config's DeepPRT network (16x16, widths 8 16, 6 training and 2 validation frames)
and one epoch of the default config's (64x64, widths 16..192, 16 channels, 240 and 40).
"""

from __future__ import annotations

import argparse
import contextlib
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pandas as pd
import torch
from torch.utils.data import TensorDataset

from neurender import tensorboard_log, train
from neurender.prt.model import build_network

IMPORT = (
    "import time, torch; t = time.perf_counter(); "
    "from torch.utils.tensorboard import SummaryWriter; print(time.perf_counter() - t)"
)


def _images(model, batch):
    x, y = batch
    return model(x)[:, :3], y[:, :3]


def _l1(model, batch):
    x, y = batch
    return torch.nn.functional.l1_loss(model(x), y), {}


def _data(frames: int, channels: int, n: int, seed: int) -> TensorDataset:
    g = torch.Generator().manual_seed(seed)
    return TensorDataset(
        torch.rand(frames, 6, n, n, generator=g), torch.rand(frames, channels, n, n, generator=g)
    )


@contextlib.contextmanager
def _timed_logger(spent: dict[str, float]):
    """While open, :class:`TrainingLog`'s methods add their seconds up in ``spent``."""
    cls = tensorboard_log.TrainingLog
    originals = {name: getattr(cls, name) for name in ("__init__", "epoch", "close")}
    for name, method in originals.items():

        def wrapper(*args, _method=method, _name=name, **kwargs):
            start = time.perf_counter()
            out = _method(*args, **kwargs)
            spent[_name] = spent.get(_name, 0.0) + time.perf_counter() - start
            return out

        setattr(cls, name, wrapper)
    try:
        yield
    finally:
        for name, method in originals.items():
            setattr(cls, name, method)


def measure(case: str, model, train_set, val_set, epochs: int) -> dict:
    spent: dict[str, float] = {}
    # The logger's cost does not depend on the optimiser's settings: any valid ones.
    config = train.TrainConfig(
        epochs=epochs,
        batch_size=5,
        lr=1e-3,
        lr_schedule="constant",
        seed=0,
        device="cpu",
        threads=1,
    )
    with tempfile.TemporaryDirectory() as tmp, _timed_logger(spent):
        start = time.perf_counter()
        train.fit(
            model,
            train.FitData(train_set, val_set),
            _l1,
            config,
            train.FitOutputs(
                Path(tmp) / "m.pt",
                Path(tmp) / "l.csv",
                tensorboard=Path(tmp) / "tb" / tensorboard_log.MARKER,
                previews=tensorboard_log.Previews(_images),
            ),
        )
        wall = time.perf_counter() - start
    logging = sum(spent.values())
    per_epoch_log = spent["epoch"] / epochs
    return {
        "case": case,
        "epochs": epochs,
        "epoch_s": (wall - logging) / epochs,
        "log_per_epoch_s": per_epoch_log,
        "open_close_s": spent["__init__"] + spent["close"],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    args = parser.parse_args()
    torch.set_num_threads(1)
    imports = [
        float(
            subprocess.run(
                [sys.executable, "-c", IMPORT], capture_output=True, text=True, check=True
            ).stdout
        )
        for _ in range(3)
    ]
    rows = []
    torch.manual_seed(0)
    toy = torch.nn.Sequential(torch.nn.Conv2d(6, 3, 1))
    rows.append(measure("toy 8x8", toy, _data(8, 3, 8, 0), _data(4, 3, 8, 1), 4))
    torch.manual_seed(0)
    smoke = build_network(16, [8, 16], 1)
    rows.append(measure("prt smoke 16x16", smoke, _data(6, 16, 16, 0), _data(2, 16, 16, 1), 2))
    torch.manual_seed(0)
    default = build_network(16, [16, 32, 64, 128, 192], 1)
    rows.append(
        measure("prt default 64x64", default, _data(240, 16, 64, 0), _data(40, 16, 64, 1), 1)
    )
    table = pd.DataFrame(rows)
    table["import_s"] = min(imports)
    table["overhead_per_epoch_pct"] = 100 * table.log_per_epoch_s / table.epoch_s
    args.out.parent.mkdir(parents=True, exist_ok=True)
    table.round(4).to_csv(args.out, index=False)
    print(table.round(4).to_string(index=False))


if __name__ == "__main__":
    main()
