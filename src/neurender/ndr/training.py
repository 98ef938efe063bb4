"""Training one NDR variant (paper 3.3) with :func:`neurender.train.fit`.

Every variant but ``pix2pix`` minimises :func:`neurender.ndr.model.loss_terms`. ``pix2pix``
trains as published (Isola et al. 2017): L1 on the tone-mapped ``I_R`` in [-1, 1] within
the mask, plus a conditional PatchGAN loss (Adam betas 0.5, 0.999).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from typing import Any

import torch

from neurender import io, train
from neurender.display import reinhard
from neurender.ndr.buffers import NDRDataset
from neurender.ndr.model import (
    NDRModel,
    architecture,
    compose,
    loss_terms,
    model_input_channels,
    network_input,
)
from neurender.ndr.variants import VARIANTS, Variant
from neurender.nn.pix2pix import NLayerDiscriminator, init_weights
from neurender.tensorboard_log import Previews, dssim_metric

Batch = dict[str, torch.Tensor]


def pix2pix_losses(variant: Variant, cfg: Mapping[str, Any]) -> tuple[Callable, train.Adversary]:
    """pix2pix's generator loss (``l1_weight`` x L1 + ``gan_weight`` x GAN) and its
    PatchGAN adversary (``ndf`` filters), in the form :func:`neurender.train.fit` takes."""
    discriminator = init_weights(NLayerDiscriminator(model_input_channels(variant) + 3, cfg["ndf"]))
    bce = torch.nn.BCEWithLogitsLoss()

    def condition_and_target(batch: Batch) -> tuple[torch.Tensor, torch.Tensor]:
        """pix2pix works in [-1, 1]: the input buffers and the tone-mapped ``I_R``."""
        x = network_input(batch, variant.inputs) * 2 - 1
        real = reinhard(compose(batch["I_D"], batch["I_S"], batch)["I_R"]) * 2 - 1
        return x, real

    def generator_loss(m: NDRModel, batch: Batch):
        x, real = condition_and_target(batch)
        fake = m.tone_mapped(batch)["I_R"] * 2 - 1
        l1 = ((fake - real).abs() * batch["mask"]).mean()
        loss = cfg["l1_weight"] * l1
        logs = {"l1": l1.item()}
        if m.training:
            logits = discriminator(torch.cat([x, fake], 1))
            gan = bce(logits, torch.ones_like(logits))
            loss = loss + cfg["gan_weight"] * gan
            logs["gan"] = gan.item()
        return loss, logs, fake.detach()

    def discriminator_loss(module: torch.nn.Module, batch: Batch, fake: torch.Tensor):
        x, real = condition_and_target(batch)
        r, f = module(torch.cat([x, real], 1)), module(torch.cat([x, fake], 1))
        return 0.5 * (bce(r, torch.ones_like(r)) + bce(f, torch.zeros_like(f))), {}

    return generator_loss, train.Adversary(discriminator, discriminator_loss)


def preview_images(model: NDRModel, batch: Batch) -> tuple[torch.Tensor, torch.Tensor]:
    """Predicted and true tone-mapped ``I_R`` in [0, 1), background zeroed, for the
    TensorBoard previews (their metric: DSSIM, the stage's loss)."""
    truth = reinhard(compose(batch["I_D"], batch["I_S"], batch)["I_R"])
    return reinhard(model(batch)["I_R"]) * batch["mask"], truth * batch["mask"]


def train_variant(
    name: str,
    train_files: dict[str, str],
    val_files: dict[str, str],
    cfg: Mapping[str, Any],
    threads: int,
    checkpoint: str,
    log_csv: str,
    data_key: str = "",
    tensorboard: str | None = None,
    variant: Variant | None = None,
) -> NDRModel:
    """Train variant ``name`` on a split's ``train_files`` and ``val_files`` (each ``dir``,
    ``manifest``, ``lighting``); ``data_key`` fingerprints them, ``tensorboard`` is the
    marker of the run's event folder (see :class:`neurender.train.FitData` and
    :class:`~neurender.train.FitOutputs`). ``variant``: the network to train, by default
    ``VARIANTS[name]``; a study passes its own (an ablation outside the table, stored under
    ``name``, which :func:`~neurender.ndr.model.load_model` cannot rebuild). Returns the
    model with the best validation epoch's weights.

    ``cfg``: ``seed``, ``device``, ``mask_erosion``, ``batch_size``, ``lr``,
    ``lr_schedule``, ``epochs`` (the same for every variant), the variant's
    :func:`~neurender.ndr.model.architecture` keys and, for ``pix2pix``, ``ndf``,
    ``l1_weight`` and ``gan_weight``.
    """
    if variant is None:
        if name not in VARIANTS:
            raise KeyError(f"NDR variant {name!r}: expected one of {sorted(VARIANTS)}")
        variant = VARIANTS[name]
    torch.manual_seed(cfg["seed"])
    erosion, limit = cfg["mask_erosion"], io.IN_MEMORY_LIMIT_BYTES
    train_set = NDRDataset.from_files(train_files, erosion, max_bytes=limit)
    val_set = NDRDataset.from_files(val_files, erosion, max_bytes=limit)
    arch = architecture(variant, cfg)
    model = NDRModel(variant, **arch)
    config = train.TrainConfig.from_stage(cfg, threads, epochs=cfg["epochs"])
    loss_fn, adversary = loss_terms, None
    if variant.arch == "pix2pix":
        config = dataclasses.replace(config, betas=(0.5, 0.999))
        loss_fn, adversary = pix2pix_losses(variant, cfg)
    train.fit(
        model,
        train.FitData(train_set, val_set, data_key),
        loss_fn,
        config,
        train.FitOutputs(
            checkpoint,
            log_csv,
            extra={"variant": name, **arch},
            tensorboard=tensorboard,
            previews=Previews(preview_images, dssim_metric),
        ),
        adversary,
    )
    return model
