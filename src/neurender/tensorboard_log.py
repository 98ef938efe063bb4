"""TensorBoard event files of a training run, for ``tensorboard --logdir results/tensorboard``.

:func:`neurender.train.fit` opens a :class:`TrainingLog` in the folder of a rule's marker
file (``results/tensorboard/<method>/<model>/run.json``) and calls :meth:`TrainingLog.epoch`
after every epoch. Each method supplies only :class:`Previews`: how a batch becomes
prediction and reference images and, where the stage has one, its image metric.

Written per epoch (the step is the 1-based epoch):

* scalars: every value of the epoch's history row (``train_loss`` as ``train/loss``,
  ``val_dssim_I_R`` as ``val/dssim_I_R``), ``lr`` (the learning rate at the epoch's end),
  ``seconds_per_epoch`` (training and validation, without this logging) and the previews'
  metrics as ``previews/<name>``;
* images ``previews/prediction``, ``previews/reference`` and ``previews/error``
  (``|prediction - reference|``): the first :data:`PREVIEW_COUNT` validation samples,
  3-channel in [0, 1], at most :data:`PREVIEW_SIZE` pixels on a side.

A resumed run continues the same curves: the writer's ``purge_step`` is the first epoch it
writes, so TensorBoard drops what an interrupted run had written for that epoch and later.
A fresh run removes the folder's old event files. Event files are appended to as training
goes (they cannot be atomic); the marker is written atomically when training finishes.
Without the ``tensorboard`` package training runs as before, with one warning.
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import torch
from torch.utils.data import Dataset, default_collate

from neurender import io, metrics
from neurender.devices import to_device

log = logging.getLogger(__name__)

#: Validation samples shown every epoch (the first ones of the split).
PREVIEW_COUNT = 4
#: Longest side of a preview image in pixels (larger ones are area-downsampled).
PREVIEW_SIZE = 128
#: The marker's name inside a run's event folder.
MARKER = "run.json"

#: ``(model, batch) -> (prediction, reference)``, each ``(B, 3, H, W)`` in [0, 1].
ImagesFn = Callable[[torch.nn.Module, Any], tuple[torch.Tensor, torch.Tensor]]
#: ``(prediction, reference) -> {name: value}`` of the preview images.
MetricsFn = Callable[[torch.Tensor, torch.Tensor], Mapping[str, float]]

_warned_missing = False


@dataclasses.dataclass(frozen=True)
class Previews:
    """What a method shows of its validation samples (see the module doc)."""

    images: ImagesFn
    metrics: MetricsFn | None = None
    count: int = PREVIEW_COUNT


def ssim_metric(prediction: torch.Tensor, reference: torch.Tensor) -> dict[str, float]:
    """``{"ssim": mean SSIM}`` of two ``(B, 3, H, W)`` image batches in [0, 1]."""
    return {"ssim": float(metrics.ssim(prediction, reference).mean())}


def dssim_metric(prediction: torch.Tensor, reference: torch.Tensor) -> dict[str, float]:
    """``{"dssim": mean DSSIM}`` of two ``(B, 3, H, W)`` image batches in [0, 1]."""
    return {"dssim": float(metrics.dssim(prediction, reference).mean())}


def scalar_tag(key: str) -> str:
    """The TensorBoard tag of a history key: ``val_dssim_I_R`` -> ``val/dssim_I_R``."""
    split, _, name = key.partition("_")
    return f"{split}/{name}" if name else key


def _summary_writer():
    """``torch.utils.tensorboard.SummaryWriter``, or None (one warning) without tensorboard."""
    global _warned_missing
    try:
        from torch.utils.tensorboard import SummaryWriter
    except ImportError as err:
        if not _warned_missing:
            log.warning("no TensorBoard event files: %s (pip install tensorboard)", err)
            _warned_missing = True
        return None
    return SummaryWriter


def _shrink(images: torch.Tensor, size: int) -> torch.Tensor:
    """``(B, 3, H, W)`` on the CPU, in [0, 1], the longer side at most ``size``."""
    images = images.detach().float().cpu().clamp(0, 1)
    longest = max(images.shape[-2:])
    if longest > size:
        scale = size / longest
        shape = [max(1, round(s * scale)) for s in images.shape[-2:]]
        images = torch.nn.functional.interpolate(images, size=shape, mode="area")
    return images


class TrainingLog:
    """The event files of one training run (a no-op when ``folder`` is None or tensorboard
    is missing). Open it with the first epoch this process trains; see the module doc."""

    def __init__(
        self,
        marker: str | Path | None,
        previews: Previews | None,
        val_set: Dataset | None,
        device: torch.device,
        first_step: int,
    ):
        self.marker = Path(marker) if marker is not None else None
        self.previews = previews
        self.device = device
        self.steps: list[int] = []
        self.tags: set[str] = set()
        self.writer = None
        writer_class = _summary_writer() if self.marker is not None else None
        if writer_class is None:
            return
        folder = self.marker.parent
        folder.mkdir(parents=True, exist_ok=True)
        self.marker.unlink(missing_ok=True)  # the run is not finished until close()
        if first_step <= 1:  # a fresh run: an earlier run's curves are not this one's
            for old in folder.glob("events.out.tfevents.*"):
                old.unlink()
        self.writer = writer_class(str(folder), purge_step=first_step)
        self.batch = None
        if previews is not None and val_set is not None and len(val_set):
            with torch.random.fork_rng(devices=[]):  # reading samples never moves training's RNG
                count = min(previews.count, len(val_set))
                self.batch = default_collate([val_set[i] for i in range(count)])

    def epoch(
        self,
        step: int,
        row: Mapping[str, float],
        lr: float,
        seconds: float,
        model: torch.nn.Module,
    ) -> None:
        """Write epoch ``step``'s scalars (``row``: the history keys ``train_*``/``val_*``)
        and the previews of ``model`` (left in eval mode; training sets its own mode)."""
        if self.writer is None:
            return
        scalars = {scalar_tag(k): float(v) for k, v in row.items() if k != "epoch"}
        scalars |= {"lr": float(lr), "seconds_per_epoch": float(seconds)}
        if self.batch is not None:
            scalars |= self._write_previews(step, model)
        for tag, value in scalars.items():
            self.writer.add_scalar(tag, value, step)
        self.tags |= set(scalars)
        self.steps.append(step)
        self.writer.flush()  # a live view sees every finished epoch

    def _write_previews(self, step: int, model: torch.nn.Module) -> dict[str, float]:
        model.eval()
        with torch.no_grad(), torch.random.fork_rng(devices=[]):
            pred, ref = self.previews.images(model, to_device(self.batch, self.device))
            pred, ref = pred.detach().float().clamp(0, 1), ref.detach().float().clamp(0, 1)
            values = dict(self.previews.metrics(pred, ref)) if self.previews.metrics else {}
        images = {"prediction": pred, "reference": ref, "error": (pred - ref).abs()}
        for name, batch in images.items():
            self.writer.add_images(f"previews/{name}", _shrink(batch, PREVIEW_SIZE), step)
        return {f"previews/{k}": float(v) for k, v in values.items()}

    def close(self) -> None:
        """Flush and close the event file; write the marker (what was logged)."""
        if self.marker is None:
            return
        written = self.writer is not None
        if written:
            self.writer.close()
        self.marker.parent.mkdir(parents=True, exist_ok=True)
        summary = {
            "event_files": sorted(p.name for p in self.marker.parent.glob("events.out.tfevents.*")),
            "steps_this_process": self.steps,
            "scalars": sorted(self.tags),
            "tensorboard": written,
        }
        io.write_json(self.marker, summary, indent=1)
