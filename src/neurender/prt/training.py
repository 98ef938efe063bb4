"""Training one DeepPRT network (one object, one material) with the shared loop."""

from __future__ import annotations

import dataclasses
import logging
import time

import numpy as np
import torch
from torch.utils.data import TensorDataset

from neurender import train
from neurender.nn.unet import ResUNet, count_parameters
from neurender.prt import unshadowed
from neurender.prt.frames import Split
from neurender.prt.local_model import LocalConfig, ShadowingTransfer
from neurender.prt.model import Normalisation, build_network, raw_inputs
from neurender.tensorboard_log import Previews

log = logging.getLogger(__name__)


def _l1_loss(model: torch.nn.Module, batch) -> tuple[torch.Tensor, dict[str, float]]:
    x, y = batch
    return torch.nn.functional.l1_loss(model(x), y), {}


def _previews(model: torch.nn.Module, batch) -> tuple[torch.Tensor, torch.Tensor]:
    """The first three transfer channels in network units (each spans about [0, 1]),
    predicted and true. The stage's metric, SSIM of rendered images, needs the evaluation's
    light and camera; its validation L1 is logged as ``val/loss``."""
    x, y = batch
    return model(x)[:, :3], y[:, :3]


def train_deepprt(
    train_split: Split,
    val_split: Split,
    material: str,
    cfg: dict,
    threads: int,
    checkpoint: str,
    log_csv: str,
    data_key: str = "",
    tensorboard: str | None = None,
) -> ResUNet:
    """Train one DeepPRT network (one object, one material) with the shared loop
    (``data_key``: the training data's fingerprint; ``tensorboard``: the marker of its
    event folder; see :class:`neurender.train.FitData` and
    :class:`~neurender.train.FitOutputs`)."""
    torch.manual_seed(cfg["seed"])
    norm = Normalisation.fit(train_split, material, residual=cfg["residual_targets"])
    make = lambda s: TensorDataset(  # noqa: E731
        torch.from_numpy(norm.inputs(s)), torch.from_numpy(norm.encode(s.targets(material)))
    )
    out_channels = train_split.targets(material).shape[1]
    # Channels-last weights make oneDNN (CPU) and cuDNN pick their faster NHWC kernels:
    # a training step of the default network takes 12% less time on the CPU.
    model = build_network(out_channels, cfg["widths"], cfg["blocks"]).to(
        memory_format=torch.channels_last
    )
    config = train.TrainConfig.from_stage(cfg, threads)
    start = time.perf_counter()
    train.fit(
        model,
        train.FitData(make(train_split), make(val_split), data_key),
        _l1_loss,
        config,
        train.FitOutputs(
            checkpoint,
            log_csv,
            extra={
                "normalisation": norm.state(),
                "widths": list(cfg["widths"]),
                "blocks": cfg["blocks"],
                "out_channels": out_channels,
                "material": material,
                "parameters": count_parameters(model),
            },
            tensorboard=tensorboard,
            previews=Previews(_previews),
        ),
    )
    log.info("trained %s in %.1f s", checkpoint, time.perf_counter() - start)
    return model


def _shadowing_loss(model, batch) -> tuple[torch.Tensor, dict[str, float]]:
    """Mean squared error of the core's normalised shadowing term (the base estimate is
    not learnt); the batch is raw inputs, their disks' occlusion and that term, encoded,
    all computed once (:func:`train_local`).

    Squared, not absolute: the targets are Monte Carlo estimates, whose conditional mean
    is the true transfer, while L1 fits their conditional median, which is biased where
    the noise is skewed (a few rays hitting a lightly occluded point). Measured in
    docs/methods/prt.md (default config: the head's test diffuse SSIM 0.9950 to 0.9967)."""
    x, occlusion, z = batch
    return torch.nn.functional.mse_loss(model.shadowing(x, occlusion), z), {}


def _shadowing_previews(model, batch) -> tuple[torch.Tensor, torch.Tensor]:
    """The first three channels of the normalised shadowing term, predicted and true,
    shown as ``0.5 + z / 4`` (the dilated core's term has unit standard deviation per
    channel, so +-2 standard deviations span [0, 1]); ``val/loss`` is its squared error."""
    x, occlusion, z = batch
    return 0.5 + model.shadowing(x, occlusion)[:, :3] / 4, 0.5 + z[:, :3] / 4


def shadowing_training(cfg: dict) -> dict:
    """``cfg`` with the shadowing variant's own batch size and learning rate (config keys
    ``shadowing_batch_size``, ``shadowing_lr``) as the ``batch_size`` and ``lr`` that
    :func:`train_local`'s loop reads (``batch_size`` and ``lr`` are the paper form's)."""
    return cfg | {"batch_size": cfg["shadowing_batch_size"], "lr": cfg["shadowing_lr"]}


def train_local(
    train_split: Split,
    val_split: Split,
    local_cfg: LocalConfig,
    cfg: dict,
    threads: int,
    checkpoint: str,
    log_csv: str,
    light: np.ndarray | None = None,
    data_key: str = "",
    tensorboard: str | None = None,
) -> ShadowingTransfer:
    """Train the shadowing variant (:mod:`neurender.prt.local_model`) with the shared loop.

    Args:
        local_cfg: its architecture and material.
        cfg: training keys (:meth:`neurender.train.TrainConfig.from_stage`) and ``seed``.
        light: ``(K, 3)`` SH light of the glossy targets (needed for glossy).
        data_key, tensorboard: as in :func:`train_deepprt`.

    Returns:
        the trained wrapper with the best validation epoch's weights.
    """
    torch.manual_seed(cfg["seed"])
    material = local_cfg.material
    coeffs = light_k = None
    if material == "glossy":
        if light is None:
            raise ValueError("training the glossy shadowing variant needs the SH light")
        light_k = np.ascontiguousarray(light[: local_cfg.n_bands**2])
        coeffs = unshadowed.glossy_polynomial(light_k)
    model = ShadowingTransfer(local_cfg, coeffs, light_k)
    inputs = {"train": raw_inputs(train_split), "val": raw_inputs(val_split)}
    # The base (unshadowed minus disks) and the disks' occlusion are fixed, so each
    # frame's shadowing term and the core's occlusion input are computed once here rather
    # than at every step.
    estimates = {name: model.estimates_of(inputs[name]) for name in inputs}
    gaps = {
        name: split.targets(material) - estimates[name][0]
        for name, split in (("train", train_split), ("val", val_split))
    }
    model.fit_normalisation(gaps["train"], estimates["train"][1])
    make = lambda name: TensorDataset(  # noqa: E731
        torch.from_numpy(inputs[name]),
        torch.from_numpy(estimates[name][1]),
        model.encode(torch.from_numpy(gaps[name])),
    )
    config = train.TrainConfig.from_stage(cfg, threads)
    start = time.perf_counter()
    train.fit(
        model,
        train.FitData(make("train"), make("val"), data_key),
        _shadowing_loss,
        config,
        train.FitOutputs(
            checkpoint,
            log_csv,
            extra={
                "local_config": dataclasses.asdict(local_cfg),
                "glossy_coeffs": None if coeffs is None else torch.from_numpy(coeffs),
                "light": None if light_k is None else torch.from_numpy(light_k),
                "material": material,
                "parameters": count_parameters(model),
            },
            tensorboard=tensorboard,
            previews=Previews(_shadowing_previews),
        ),
    )
    log.info("trained %s in %.1f s", checkpoint, time.perf_counter() - start)
    return model.eval()
