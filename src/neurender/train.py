"""The one training loop every neurender model uses.

* ``device: auto`` picks CUDA when present, else the CPU with ``threads`` torch threads.
* Fixed seed: weights, shuffling (a generator seeded per epoch) and dropout are
  reproducible, including across an interruption and resume.
* After every epoch the full state (model, optimiser, scheduler, RNG, history) goes to a
  resume file beside the output; a rerun continues from the last finished epoch if the
  training config is unchanged. Snakemake deletes a failed job's declared outputs, so the
  resume file is deliberately not one of them; it is removed once training completes.
* Losses are logged as tidy CSV (epoch, split, metric, value); a NaN/inf loss stops
  training with an error naming the epoch and step.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import random
import sys
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import torch
from torch.utils.data import DataLoader, Dataset
from tqdm import tqdm

from neurender import io

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


@dataclasses.dataclass
class TrainConfig:
    epochs: int = 10  # passes over the training set
    batch_size: int = 5
    lr: float = 1e-3  # Adam learning rate
    lr_schedule: str = "cosine"  # "constant" or "cosine" (decay to lr_min_ratio * lr)
    lr_min_ratio: float = 0.05
    weight_decay: float = 0.0
    betas: tuple[float, float] = (0.9, 0.999)
    seed: int = 0
    device: str = "auto"  # "auto", "cpu", "cuda", "cuda:1", ...
    threads: int = 1  # torch CPU threads (the Snakemake rule's threads)

    @classmethod
    def from_dict(cls, values: Mapping[str, Any]) -> TrainConfig:
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(values) - names)
        if unknown:
            raise KeyError(f"unknown training keys {unknown}; expected some of {sorted(names)}")
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


def resolve_device(name: str = "auto", threads: int = 1) -> torch.device:
    """Torch device for a config value; on the CPU also sets the torch thread count."""
    if name == "auto":
        name = "cuda" if torch.cuda.is_available() else "cpu"
    device = torch.device(name)
    if device.type == "cuda" and not torch.cuda.is_available():
        raise RuntimeError(
            f"device {name!r} requested but CUDA is not available; use device: auto or cpu"
        )
    if device.type == "cpu":
        torch.set_num_threads(max(1, threads))
    return device


def seed_everything(seed: int) -> None:
    """Seed Python, numpy and torch (CPU and CUDA)."""
    random.seed(seed)
    np.random.seed(seed % 2**32)  # noqa: NPY002 - seeds code that uses the legacy global RNG
    torch.manual_seed(seed)


def to_device(batch: Any, device: torch.device) -> Any:
    """Move tensors in a (nested) batch to ``device``."""
    if isinstance(batch, torch.Tensor):
        return batch.to(device, non_blocking=True)
    if isinstance(batch, Mapping):
        return {k: to_device(v, device) for k, v in batch.items()}
    if isinstance(batch, list | tuple):
        return type(batch)(to_device(v, device) for v in batch)
    return batch


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


def _evaluate(model, loader, loss_fn, device) -> dict[str, float]:
    model.eval()
    sums: dict[str, float] = {}
    count = 0
    with torch.no_grad():
        for batch in loader:
            loss, logs, *_ = loss_fn(model, to_device(batch, device))
            n = len(next(iter(batch.values())) if isinstance(batch, Mapping) else batch[0])
            for key, value in {"loss": loss.item(), **logs}.items():
                sums[key] = sums.get(key, 0.0) + float(value) * n
            count += n
    return {k: v / max(count, 1) for k, v in sums.items()}


def fit(
    model: torch.nn.Module,
    train_set: Dataset,
    val_set: Dataset | None,
    loss_fn: LossFn,
    config: TrainConfig,
    checkpoint_path: str | Path,
    log_path: str | Path,
    extra_state: Mapping[str, Any] | None = None,
    adversary: Adversary | None = None,
) -> pd.DataFrame:
    """Train ``model`` with Adam and write its final checkpoint and loss log.

    Args:
        model: module; moved to the resolved device.
        train_set, val_set: map-style datasets yielding tensors, tuples or dicts of tensors.
        loss_fn: ``(model, batch) -> (scalar loss, {name: float})`` or ``(loss, logs,
            aux)`` with ``aux`` handed to the adversary; the batch is already on the device.
        config: training hyper-parameters.
        checkpoint_path: final checkpoint (``torch.save`` dict with ``model`` = the weights
            of the best validation epoch, ``last_model``, ``config``, ``history``, ``extra``).
        log_path: tidy CSV of losses, columns ``epoch, split, metric, value``.
        extra_state: stored under ``extra`` in the checkpoint (e.g. target normalisation).
        adversary: optional discriminator, trained after every model step and stored in
            the checkpoint as ``adversary``.

    Returns:
        The loss history as a tidy data frame.
    """
    device = resolve_device(config.device, config.threads)
    model.to(device)
    optimizer = torch.optim.Adam(
        model.parameters(), lr=config.lr, betas=config.betas, weight_decay=config.weight_decay
    )
    steps_per_epoch = math.ceil(len(train_set) / config.batch_size)
    scheduler = _make_scheduler(optimizer, config, config.epochs * steps_per_epoch)
    adv_optimizer = None
    if adversary is not None:
        adversary.module.to(device)
        adv_optimizer = torch.optim.Adam(
            adversary.module.parameters(), lr=config.lr, betas=config.betas
        )
    config_dict = dataclasses.asdict(config)
    config_dict.pop("device")  # the same run may resume on another device
    config_dict.pop("threads")
    resume_path = resume_path_for(checkpoint_path)

    history: list[dict[str, Any]] = []
    start_epoch, best_val, best_state = 0, math.inf, None
    if resume_path.is_file():
        state = torch.load(resume_path, map_location=device, weights_only=False)
        if state["config"] == config_dict:
            model.load_state_dict(state["model"])
            optimizer.load_state_dict(state["optimizer"])
            scheduler.load_state_dict(state["scheduler"])
            torch.set_rng_state(state["torch_rng"])
            if adversary is not None:
                adversary.module.load_state_dict(state["adversary"])
                adv_optimizer.load_state_dict(state["adversary_optimizer"])
            start_epoch, best_val = state["epoch"], state["best_val"]
            best_state, history = state["best_model"], state["history"]
            log.info("resuming %s after epoch %d", checkpoint_path, start_epoch)
        else:
            log.info("ignoring %s: it was written with another training config", resume_path)

    val_loader = (
        DataLoader(val_set, batch_size=config.batch_size, shuffle=False)
        if val_set is not None
        else None
    )
    epochs = tqdm(
        range(start_epoch, config.epochs), desc="epochs", file=sys.stderr, mininterval=2.0
    )
    for epoch in epochs:
        model.train()
        if adversary is not None:
            adversary.module.train()
        shuffle = torch.Generator().manual_seed(config.seed * 100_003 + epoch)
        loader = DataLoader(
            train_set, batch_size=config.batch_size, shuffle=True, generator=shuffle
        )
        sums: dict[str, float] = {}
        for step, batch in enumerate(loader):
            batch = to_device(batch, device)
            loss, logs, *aux = loss_fn(model, batch)
            _check_finite(loss, "training", epoch, step, checkpoint_path)
            optimizer.zero_grad(set_to_none=True)
            loss.backward()
            optimizer.step()
            scheduler.step()
            if adversary is not None:
                adv_loss, adv_logs = adversary.loss_fn(
                    adversary.module, batch, aux[0] if aux else None
                )
                _check_finite(adv_loss, "adversary", epoch, step, checkpoint_path)
                adv_optimizer.zero_grad(set_to_none=True)  # drops what the model's loss left
                adv_loss.backward()
                adv_optimizer.step()
                logs = {**logs, "adversary_loss": adv_loss.item(), **adv_logs}
            for key, value in {"loss": loss.item(), **logs}.items():
                sums[key] = sums.get(key, 0.0) + float(value)
        row = {f"train_{k}": v / max(steps_per_epoch, 1) for k, v in sums.items()}
        if val_loader is not None:
            row.update(
                {f"val_{k}": v for k, v in _evaluate(model, val_loader, loss_fn, device).items()}
            )
        history.append({"epoch": epoch + 1, **row})
        score = row.get("val_loss", row["train_loss"])
        if score < best_val:
            best_val = score
            best_state = {k: v.detach().cpu().clone() for k, v in model.state_dict().items()}
        epochs.set_postfix({k: f"{v:.4g}" for k, v in row.items() if k.endswith("loss")})
        _atomic_torch_save(
            {
                "model": model.state_dict(),
                "optimizer": optimizer.state_dict(),
                "scheduler": scheduler.state_dict(),
                "torch_rng": torch.get_rng_state(),
                "epoch": epoch + 1,
                "best_val": best_val,
                "best_model": best_state,
                "history": history,
                "config": config_dict,
                **(
                    {
                        "adversary": adversary.module.state_dict(),
                        "adversary_optimizer": adv_optimizer.state_dict(),
                    }
                    if adversary is not None
                    else {}
                ),
            },
            resume_path,
        )
        io.write_csv(log_path, history_frame(history))

    final = {
        "model": best_state if best_state is not None else model.state_dict(),
        "last_model": {k: v.detach().cpu() for k, v in model.state_dict().items()},
        "config": config_dict,
        "history": history,
        "best_val": best_val,
        "extra": dict(extra_state or {}),
        **({"adversary": adversary.module.state_dict()} if adversary is not None else {}),
    }
    _atomic_torch_save(final, Path(checkpoint_path))
    io.write_csv(log_path, history_frame(history))
    resume_path.unlink(missing_ok=True)
    if best_state is not None:
        model.load_state_dict(best_state)
    return history_frame(history)


def _check_finite(loss: torch.Tensor, what: str, epoch: int, step: int, checkpoint_path) -> None:
    if not torch.isfinite(loss):
        raise FloatingPointError(
            f"{what} loss became {loss.item()} at epoch {epoch + 1}, step {step + 1} "
            f"(checkpoint {checkpoint_path}); lower the learning rate or check the data"
        )


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


def load_checkpoint(path: str | Path, device: torch.device | str = "cpu") -> dict[str, Any]:
    """Load a checkpoint written by :func:`fit`, naming the file on failure."""
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"checkpoint {p} does not exist")
    try:
        return torch.load(p, map_location=device, weights_only=False)
    except Exception as err:
        raise OSError(f"cannot read checkpoint {p}: {err}") from err
