"""The one training loop every neurender model uses.

* ``device: auto`` picks CUDA when present, else the CPU with ``threads`` torch threads
  (:func:`neurender.devices.resolve_device`).
* Fixed seed: weights, shuffling (a generator seeded per epoch) and dropout are
  reproducible, including across an interruption and resume.
* Checkpoints and resume files hold only tensors and plain types (numbers, strings,
  lists, tuples, dicts) and are read with ``torch.load(weights_only=True)``: a results
  folder or resume file from someone else cannot run code when it is loaded.
* After every epoch the full state (model, optimiser, scheduler, CPU and CUDA RNG,
  history) goes to a resume file beside the output; a rerun continues from the last
  finished epoch if the file was written for the same data, architecture and training
  config (:func:`resume_key`), and discards it with a log line otherwise. Snakemake
  deletes a failed job's declared outputs, so the resume file is deliberately not one of
  them; it is removed once training completes.
* Losses are logged as tidy CSV (epoch, split, metric, value); a NaN/inf training or
  validation loss stops training with an error naming the epoch and step.
* Given a marker file, every epoch's scalars and validation previews also go to
  TensorBoard event files beside it (:mod:`neurender.tensorboard_log`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import logging
import math
import os
import pickle
import sys
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import pandas as pd
import torch
from torch.utils.data import DataLoader, Dataset
from tqdm import tqdm

from neurender import io, tensorboard_log
from neurender.devices import resolve_device, to_device

log = logging.getLogger(__name__)

LossFn = Callable[[torch.nn.Module, Any], tuple]


@dataclasses.dataclass
class Adversary:
    """A second network trained against the model (a GAN discriminator).

    After each model step, ``loss_fn(module, batch, aux)`` gives the adversary's loss, where
    ``aux`` is the third value the model's loss function returned (e.g. the detached fake
    images), and the adversary takes its own Adam step with the model's hyper-parameters.
    """

    module: torch.nn.Module
    loss_fn: Callable[[torch.nn.Module, Any, Any], tuple[torch.Tensor, Mapping[str, float]]]


@dataclasses.dataclass(kw_only=True)
class TrainConfig:
    """A training run's settings. The fields without a default are config keys (a method's
    ``*_model`` section, ``seed``, ``device``) or the rule's threads, whose defaults live in
    the schema only; the others are the loop's own constants."""

    epochs: int  # passes over the training set
    batch_size: int
    lr: float  # Adam learning rate
    lr_schedule: str  # "constant" or "cosine" (decay to lr_min_ratio * lr)
    lr_min_ratio: float = 0.05
    weight_decay: float = 0.0
    betas: tuple[float, float] = (0.9, 0.999)
    seed: int
    device: str  # "auto", "cpu", "cuda", "cuda:1", ...
    threads: int  # torch CPU threads (the Snakemake rule's threads)

    @classmethod
    def from_dict(cls, values: Mapping[str, Any]) -> TrainConfig:
        fields = dataclasses.fields(cls)
        names = {f.name for f in fields}
        unknown = sorted(set(values) - names)
        if unknown:
            raise KeyError(f"unknown training keys {unknown}; expected some of {sorted(names)}")
        required = {f.name for f in fields if f.default is dataclasses.MISSING}
        missing = sorted(required - set(values))
        if missing:
            raise KeyError(f"training keys {missing} missing (their defaults are the schema's)")
        kwargs = dict(values)
        if "betas" in kwargs:
            kwargs["betas"] = tuple(kwargs["betas"])
        return cls(**kwargs)

    @classmethod
    def from_stage(cls, cfg: Mapping[str, Any], threads: int, **overrides: Any) -> TrainConfig:
        """The training keys of a stage's config subtree (others are ignored), plus overrides."""
        names = {f.name for f in dataclasses.fields(cls)} - {"threads"}
        return cls.from_dict(
            {**{k: v for k, v in cfg.items() if k in names}, "threads": threads, **overrides}
        )


def _check_type(value: Any, types: type | tuple[type, ...], where: str, expected: str) -> None:
    if not isinstance(value, types):
        raise TypeError(f"{where} is a {type(value).__name__}; expected {expected}")


def _check_dataset(value: Any, where: str) -> None:
    if not (hasattr(value, "__len__") and hasattr(value, "__getitem__")):
        raise TypeError(f"{where} is a {type(value).__name__}; expected a map-style dataset")


@dataclasses.dataclass(frozen=True)
class FitData:
    """What :func:`fit` trains on: map-style datasets (``__len__``, ``__getitem__``) whose
    samples are tensors, tuples or dicts of tensors."""

    train: Dataset  # at least one sample; reshuffled every epoch from the config's seed
    val: Dataset | None  # None: the best epoch is the one of lowest training loss
    key: str = ""  # the data's fingerprint (e.g. io.checksum of its files); see resume_key

    def __post_init__(self):
        _check_dataset(self.train, "FitData.train")
        if len(self.train) == 0:
            raise ValueError("FitData.train is empty; expected at least one sample")
        if self.val is not None:
            _check_dataset(self.val, "FitData.val")
        _check_type(self.key, str, "FitData.key", "a str")


@dataclasses.dataclass(frozen=True)
class FitOutputs:
    """What :func:`fit` writes (paths given as str are kept as Path). The checkpoint is a
    ``torch.save`` dict: ``model`` (the best validation epoch's weights), ``last_model``,
    ``config``, ``history``, ``best_val``, ``extra`` and, with an adversary, ``adversary``."""

    checkpoint: Path  # the final checkpoint; the resume file is resume_path_for(checkpoint)
    log: Path  # tidy CSV of losses: epoch, split, metric, value
    # the checkpoint's ``extra`` (e.g. target normalisation): tensors and plain types only
    extra: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    tensorboard: Path | None = None  # marker of the TensorBoard event folder; None: no events
    previews: tensorboard_log.Previews | None = None  # validation images in it; None: none

    def __post_init__(self):
        paths = {"checkpoint": self.checkpoint, "log": self.log}
        if self.tensorboard is not None:
            paths["tensorboard"] = self.tensorboard
        for name, value in paths.items():
            _check_type(value, (str, os.PathLike), f"FitOutputs.{name}", "a str or Path")
            object.__setattr__(self, name, Path(value))  # frozen: set here only
        _check_type(self.extra, Mapping, "FitOutputs.extra", "a mapping")
        object.__setattr__(self, "extra", dict(self.extra))
        check_plain(self.extra, f"FitOutputs(checkpoint={str(self.checkpoint)!r}).extra")
        if self.previews is not None:
            _check_type(self.previews, tensorboard_log.Previews, "FitOutputs.previews", "Previews")


def resume_path_for(checkpoint_path: str | Path) -> Path:
    p = Path(checkpoint_path)
    return p.with_name(p.name + ".resume")


def _make_scheduler(optimizer: torch.optim.Optimizer, config: TrainConfig, total_steps: int):
    if config.lr_schedule == "constant":
        return torch.optim.lr_scheduler.LambdaLR(optimizer, lambda step: 1.0)
    if config.lr_schedule == "cosine":
        floor = config.lr_min_ratio

        def factor(step: int) -> float:
            t = min(step / max(total_steps, 1), 1.0)
            return floor + (1.0 - floor) * 0.5 * (1.0 + math.cos(math.pi * t))

        return torch.optim.lr_scheduler.LambdaLR(optimizer, factor)
    raise ValueError(f"lr_schedule {config.lr_schedule!r}: expected 'constant' or 'cosine'")


def _atomic_torch_save(obj: Any, path: Path) -> None:
    with io.atomic_path(path) as tmp:
        torch.save(obj, tmp)


# Exact types: subclasses (numpy.float64 is a float, Snakemake's Namedlist a list) pickle
# as their own class, which weights_only refuses.
_PLAIN = {str, int, float, bool, type(None)}


def check_plain(value: Any, where: str) -> None:
    """Raise ``TypeError`` naming the key if ``value`` holds anything but tensors and plain
    types (str, int, float, bool, None, and lists, tuples and dicts of them with str or int
    keys): what :func:`load_checkpoint` reads back with ``weights_only=True``."""
    if type(value) is dict:
        for key, item in value.items():
            if type(key) not in (str, int):
                raise TypeError(f"{where} has a key {key!r} of type {type(key).__name__}")
            check_plain(item, f"{where}[{key!r}]")
    elif type(value) in (list, tuple):
        for i, item in enumerate(value):
            check_plain(item, f"{where}[{i}]")
    elif not (isinstance(value, torch.Tensor) or type(value) in _PLAIN):
        kind = f"{type(value).__module__}.{type(value).__qualname__}"
        raise TypeError(
            f"{where} is a {kind}; a checkpoint stores only tensors and plain types (str, "
            "int, float, bool, None, lists, tuples, dicts): convert it (torch.from_numpy, "
            "dataclasses.asdict, float(), list())"
        )


def _load_state(path: Path, what: str, device: torch.device | str = "cpu") -> dict[str, Any]:
    """The ``what`` (checkpoint or resume file) at ``path`` read with ``weights_only=True``;
    one holding other objects (which could run code when unpickled) or that torch cannot
    read raises ``OSError`` naming it."""
    try:
        return torch.load(path, map_location=device, weights_only=True)
    except pickle.UnpicklingError as err:
        # torch's message is a page of advice; its "WeightsUnpickler error" line says what.
        lines = [line for line in str(err).splitlines() if "WeightsUnpickler" in line]
        reason = lines[0].strip() if lines else str(err).splitlines()[0]
        raise OSError(
            f"refusing to load {what} {path}: it holds objects other than tensors and plain "
            f"types, which could run code when loaded ({reason}); delete it to train again "
            "(DeepPRT checkpoints written before its normalisation was stored as tensors "
            "hold numpy arrays)"
        ) from err
    except Exception as err:
        raise OSError(f"cannot read {what} {path}: {err}") from err


def _check_finite(
    loss: torch.Tensor, what: str, epoch: int, step: int, checkpoint_path, unit: str = "step"
) -> None:
    if not torch.isfinite(loss):
        raise FloatingPointError(
            f"{what} loss became {loss.item()} at epoch {epoch + 1}, {unit} {step + 1} "
            f"(checkpoint {checkpoint_path}); lower the learning rate or check the data"
        )


def resume_key(config: TrainConfig, model: torch.nn.Module, data_key: str = "") -> str:
    """What a resume file must match to be continued: the training config (not the device
    or threads: a run may resume elsewhere), the model's architecture (its parameter names
    and shapes) and ``data_key`` (the caller's fingerprint of the training data)."""
    config_dict = dataclasses.asdict(config)
    config_dict.pop("device")
    config_dict.pop("threads")
    shapes = [(k, tuple(v.shape)) for k, v in model.state_dict().items()]
    text = repr((sorted(config_dict.items()), shapes, data_key))
    return hashlib.sha256(text.encode()).hexdigest()


@dataclasses.dataclass
class _Run:
    """What a training run updates: the model, its optimiser and schedule, the adversary
    and its optimiser, and the record of finished epochs."""

    model: torch.nn.Module
    optimizer: torch.optim.Optimizer
    scheduler: Any
    adversary: Adversary | None
    adv_optimizer: torch.optim.Optimizer | None
    epoch: int = 0
    best_val: float = math.inf
    best_state: dict | None = None
    history: list[dict[str, Any]] = dataclasses.field(default_factory=list)

    def state(self, key: str) -> dict[str, Any]:
        """Everything a resume needs, RNG states included (CUDA's where it is used)."""
        state = {
            "key": key,
            "model": self.model.state_dict(),
            "optimizer": self.optimizer.state_dict(),
            "scheduler": self.scheduler.state_dict(),
            "torch_rng": torch.get_rng_state(),
            "cuda_rng": torch.cuda.get_rng_state_all() if torch.cuda.is_available() else None,
            "epoch": self.epoch,
            "best_val": self.best_val,
            "best_model": self.best_state,
            "history": self.history,
        }
        if self.adversary is not None:
            state["adversary"] = self.adversary.module.state_dict()
            state["adversary_optimizer"] = self.adv_optimizer.state_dict()
        return state

    def restore(self, state: dict[str, Any]) -> None:
        """Continue from :meth:`state` (loaded onto the CPU; tensors move to the model)."""
        self.model.load_state_dict(state["model"])
        self.optimizer.load_state_dict(state["optimizer"])
        self.scheduler.load_state_dict(state["scheduler"])
        torch.set_rng_state(state["torch_rng"])
        if state["cuda_rng"] is not None and torch.cuda.is_available():
            torch.cuda.set_rng_state_all(state["cuda_rng"])
        if self.adversary is not None:
            self.adversary.module.load_state_dict(state["adversary"])
            self.adv_optimizer.load_state_dict(state["adversary_optimizer"])
        self.epoch, self.best_val = state["epoch"], state["best_val"]
        self.best_state, self.history = state["best_model"], state["history"]


def load_resume(run: _Run, path: Path, key: str) -> None:
    """Continue ``run`` from the resume file at ``path`` if there is one written for
    ``key``; a stale one (other data, architecture or config) is discarded with a log line."""
    if not path.is_file():
        return
    try:
        state = _load_state(path, "resume file")
    except OSError as err:  # a torn or foreign file: start afresh rather than fail
        log.warning("discarding unreadable resume file %s (%s)", path, err)
        path.unlink()
        return
    if state.get("key") != key:
        log.warning(
            "discarding stale resume file %s: it was written for other data, another "
            "architecture or another training config",
            path,
        )
        path.unlink()
        return
    run.restore(state)
    log.info("resuming from %s after epoch %d", path, run.epoch)


def train_epoch(
    run: _Run, loader: DataLoader, loss_fn: LossFn, device: torch.device, checkpoint_path
) -> dict[str, float]:
    """One pass over ``loader``: a model step per batch, then an adversary step. Returns
    the mean of every logged value, keys prefixed ``train_``."""
    run.model.train()
    if run.adversary is not None:
        run.adversary.module.train()
    sums: dict[str, float] = {}
    for step, batch in enumerate(loader):
        batch = to_device(batch, device)
        if run.adversary is not None:
            # Through the adversary the model's loss needs gradients of its input only: its
            # weights' would be dropped before its own step (set before the graph is built).
            run.adversary.module.requires_grad_(False)
        loss, logs, *aux = loss_fn(run.model, batch)
        _check_finite(loss, "training", run.epoch, step, checkpoint_path)
        run.optimizer.zero_grad(set_to_none=True)
        loss.backward()
        run.optimizer.step()
        run.scheduler.step()
        if run.adversary is not None:
            run.adversary.module.requires_grad_(True)
            adv_loss, adv_logs = run.adversary.loss_fn(
                run.adversary.module, batch, aux[0] if aux else None
            )
            _check_finite(adv_loss, "adversary", run.epoch, step, checkpoint_path)
            run.adv_optimizer.zero_grad(set_to_none=True)
            adv_loss.backward()
            run.adv_optimizer.step()
            logs = {**logs, "adversary_loss": adv_loss.item(), **adv_logs}
        for key, value in {"loss": loss.item(), **logs}.items():
            sums[key] = sums.get(key, 0.0) + float(value)
    return {f"train_{k}": v / max(len(loader), 1) for k, v in sums.items()}


def validate(
    model, loader: DataLoader, loss_fn: LossFn, device, epoch: int, checkpoint_path
) -> dict[str, float]:
    """Sample-weighted mean of every logged value over ``loader`` in eval mode, keys
    prefixed ``val_``; a non-finite loss stops training naming the epoch and batch."""
    model.eval()
    sums: dict[str, float] = {}
    count = 0
    with torch.no_grad():
        for step, batch in enumerate(loader):
            loss, logs, *_ = loss_fn(model, to_device(batch, device))
            _check_finite(loss, "validation", epoch, step, checkpoint_path, "batch")
            n = len(next(iter(batch.values())) if isinstance(batch, Mapping) else batch[0])
            for key, value in {"loss": loss.item(), **logs}.items():
                sums[key] = sums.get(key, 0.0) + float(value) * n
            count += n
    return {f"val_{k}": v / max(count, 1) for k, v in sums.items()}


def _start(
    model: torch.nn.Module,
    adversary: Adversary | None,
    config: TrainConfig,
    train_size: int,
    device: torch.device,
) -> _Run:
    """A fresh run on ``device``: Adam for the model (and the adversary, if any) and the
    learning-rate schedule over every step of ``config.epochs``."""
    model.to(device)
    optimizer = torch.optim.Adam(
        model.parameters(), lr=config.lr, betas=config.betas, weight_decay=config.weight_decay
    )
    steps_per_epoch = math.ceil(train_size / config.batch_size)
    scheduler = _make_scheduler(optimizer, config, config.epochs * steps_per_epoch)
    adv_optimizer = None
    if adversary is not None:
        adversary.module.to(device)
        adv_optimizer = torch.optim.Adam(
            adversary.module.parameters(), lr=config.lr, betas=config.betas
        )
    return _Run(model, optimizer, scheduler, adversary, adv_optimizer)


def fit(
    model: torch.nn.Module,
    data: FitData,
    loss_fn: LossFn,
    config: TrainConfig,
    outputs: FitOutputs,
    adversary: Adversary | None = None,
) -> pd.DataFrame:
    """Train ``model`` with Adam and write its final checkpoint and loss log.

    Args:
        model: module; moved to the resolved device.
        data: the training and validation sets and the data's fingerprint (:class:`FitData`).
        loss_fn: ``(model, batch) -> (scalar loss, {name: float})`` or ``(loss, logs,
            aux)`` with ``aux`` handed to the adversary; the batch is already on the device.
        config: training hyper-parameters.
        outputs: the checkpoint, loss log and TensorBoard files, and what goes into them
            beyond the training itself (:class:`FitOutputs`).
        adversary: optional discriminator, trained after every model step and stored in
            the checkpoint as ``adversary``.

    Returns:
        The loss history as a tidy data frame.
    """
    checkpoint_path, log_path = outputs.checkpoint, outputs.log
    train_set, val_set = data.train, data.val
    device = resolve_device(config.device, config.threads)
    run = _start(model, adversary, config, len(train_set), device)
    key = resume_key(config, model, data.key)
    resume_path = resume_path_for(checkpoint_path)
    load_resume(run, resume_path, key)
    board = tensorboard_log.TrainingLog(
        outputs.tensorboard, outputs.previews, val_set, device, run.epoch + 1
    )
    val_loader = (
        DataLoader(val_set, batch_size=config.batch_size, shuffle=False)
        if val_set is not None
        else None
    )
    epochs = tqdm(range(run.epoch, config.epochs), desc="epochs", file=sys.stderr, mininterval=2)
    for epoch in epochs:
        run.epoch = epoch
        started = time.perf_counter()
        # A generator per epoch: the order of an epoch does not depend on what came before.
        shuffle = torch.Generator().manual_seed(config.seed * 100_003 + epoch)
        loader = DataLoader(
            train_set, batch_size=config.batch_size, shuffle=True, generator=shuffle
        )
        row = train_epoch(run, loader, loss_fn, device, checkpoint_path)
        if val_loader is not None:
            row |= validate(model, val_loader, loss_fn, device, epoch, checkpoint_path)
        run.history.append({"epoch": epoch + 1, **row})
        score = row.get("val_loss", row["train_loss"])
        if score < run.best_val:
            run.best_val = score
            run.best_state = {k: v.detach().cpu().clone() for k, v in model.state_dict().items()}
        epochs.set_postfix({k: f"{v:.4g}" for k, v in row.items() if k.endswith("loss")})
        lr = run.optimizer.param_groups[0]["lr"]
        board.epoch(epoch + 1, row, lr, time.perf_counter() - started, model)
        run.epoch = epoch + 1
        _atomic_torch_save(run.state(key), resume_path)
        io.write_csv(log_path, history_frame(run.history))
    _save_final(run, config, outputs.extra, checkpoint_path)
    io.write_csv(log_path, history_frame(run.history))
    board.close()
    resume_path.unlink(missing_ok=True)
    if run.best_state is not None:
        model.load_state_dict(run.best_state)
    return history_frame(run.history)


def _save_final(run: _Run, config: TrainConfig, extra: dict[str, Any], path: Path) -> None:
    """The checkpoint of a finished run: the best epoch's weights (``model``) and the last."""
    config_dict = dataclasses.asdict(config)
    config_dict.pop("device")  # the same run may be evaluated on another device
    config_dict.pop("threads")
    final = {
        "model": run.best_state if run.best_state is not None else run.model.state_dict(),
        "last_model": {k: v.detach().cpu() for k, v in run.model.state_dict().items()},
        "config": config_dict,
        "history": run.history,
        "best_val": run.best_val,
        "extra": extra,
    }
    if run.adversary is not None:
        final["adversary"] = run.adversary.module.state_dict()
    _atomic_torch_save(final, path)


def history_frame(history: list[Mapping[str, Any]]) -> pd.DataFrame:
    """Tidy ``epoch, split, metric, value`` rows from per-epoch dicts like ``val_loss``."""
    rows = []
    for entry in history:
        for key, value in entry.items():
            if key == "epoch":
                continue
            split, metric = key.split("_", 1)
            rows.append({"epoch": entry["epoch"], "split": split, "metric": metric, "value": value})
    return pd.DataFrame(rows, columns=["epoch", "split", "metric", "value"])


def epochs_trained(path: str | Path) -> int:
    """Epochs a finished run of :func:`fit` trained (its budget, for comparison tables)."""
    return len(load_checkpoint(path)["history"])


def load_checkpoint(path: str | Path, device: torch.device | str = "cpu") -> dict[str, Any]:
    """Load a checkpoint written by :func:`fit` (``weights_only=True``), naming the file on
    failure: ``FileNotFoundError`` if missing, ``OSError`` if unreadable or if it holds
    objects other than tensors and plain types."""
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"checkpoint {p} does not exist")
    return _load_state(p, "checkpoint", device)
