"""Training one metaballs variant: L1 to the ray-marched G-buffers, plus for the GAN
variants the thesis's conditional PatchGAN (pix2pix: Adam with beta1 0.5).

The loop is :func:`neurender.train.fit`; this module gives it the networks, the datasets
and the losses (see :mod:`neurender.metaballs.model` for the variants).
"""

from __future__ import annotations

from collections.abc import Mapping

import torch
from torch import nn

from neurender import io, train
from neurender.metaballs import gbuffers
from neurender.metaballs.dataset import ABDataset
from neurender.metaballs.model import build_discriminator, build_generator
from neurender.tensorboard_log import Previews, ssim_metric

SPLIT_FILES = ("dir", "manifest", "balls")


def generator_loss(
    l1_weight: float, gan_weight: float, discriminator: nn.Module | None
) -> train.LossFn:
    """``(model, (x, y)) -> (loss, logs, fake)``: ``l1_weight`` x L1(G(x), y), plus while
    training ``gan_weight`` x BCE(D(x, G(x)), real) when there is a discriminator."""
    bce = nn.BCEWithLogitsLoss()

    def loss_fn(model, batch):
        x, y = batch
        fake = model(x)
        l1 = (fake - y).abs().mean()
        loss = l1_weight * l1
        logs = {"l1": l1.item()}
        if discriminator is not None and model.training:
            logits = discriminator(torch.cat([x, fake], 1))
            gan = bce(logits, torch.ones_like(logits))
            loss = loss + gan_weight * gan
            logs["gan"] = gan.item()
        return loss, logs, fake.detach()

    return loss_fn


def discriminator_loss(module: nn.Module, batch, fake: torch.Tensor):
    """The PatchGAN's BCE on real ``(x, y)`` and faked ``(x, G(x))`` pairs, halved."""
    bce = nn.BCEWithLogitsLoss()
    x, y = batch
    real = module(torch.cat([x, y], 1))
    faked = module(torch.cat([x, fake], 1))
    loss = 0.5 * (bce(real, torch.ones_like(real)) + bce(faked, torch.zeros_like(faked)))
    return loss, {}


def preview_images(model: nn.Module, batch) -> tuple[torch.Tensor, torch.Tensor]:
    """Predicted and ray-marched colour buffers in [0, 1] (the network works in [-1, 1]),
    for the TensorBoard previews (their metric: SSIM, as the evaluation scores buffers)."""
    x, y = batch
    colour = gbuffers.COLOUR
    return (model(x)[:, colour] + 1) / 2, (y[:, colour] + 1) / 2


def split_dataset(files: Mapping[str, str], split: str, variant: str, flips: bool) -> ABDataset:
    """The :class:`ABDataset` of ``files``' ``{split}_dir``, ``_manifest`` and ``_balls``
    (on disk when larger than :data:`neurender.io.IN_MEMORY_LIMIT_BYTES`)."""
    return ABDataset(
        *(files[f"{split}_{kind}"] for kind in SPLIT_FILES),
        variant,
        flips=flips,
        max_bytes=io.IN_MEMORY_LIMIT_BYTES,
    )


def train_generator(
    files: Mapping[str, str],
    cfg: Mapping,
    threads: int,
    checkpoint: str,
    log_csv: str,
    data_key: str = "",
    tensorboard: str | None = None,
) -> None:
    """Train one variant's generator (and, when ``gan_weight > 0``, its PatchGAN); write
    its checkpoint and its tidy loss log (``data_key``: the training data's fingerprint,
    ``tensorboard``: the marker of its event folder; see :class:`neurender.train.FitData`
    and :class:`~neurender.train.FitOutputs`).

    Args:
        files: ``train_dir, train_manifest, train_balls`` and the same for ``val``.
        cfg: ``variant, seed, width, ngf, gan_weight, l1_weight, flips``, ``ndf`` when
            ``gan_weight > 0``, and the training keys of :class:`neurender.train.TrainConfig`.
    """
    torch.manual_seed(cfg["seed"])
    variant, gan_weight = cfg["variant"], cfg["gan_weight"]
    generator = build_generator(cfg["width"], cfg["ngf"], variant)
    discriminator = build_discriminator(cfg["ndf"], variant) if gan_weight > 0 else None
    train.fit(
        generator,
        train.FitData(
            split_dataset(files, "train", variant, cfg["flips"]),
            split_dataset(files, "val", variant, False),
            data_key,
        ),
        generator_loss(cfg["l1_weight"], gan_weight, discriminator),
        train.TrainConfig.from_stage(cfg, threads, betas=(0.5, 0.999)),
        train.FitOutputs(
            checkpoint,
            log_csv,
            extra={
                "width": cfg["width"],
                "ngf": cfg["ngf"],
                "gan_weight": gan_weight,
                "variant": variant,
            },
            tensorboard=tensorboard,
            previews=Previews(preview_images, ssim_metric),
        ),
        None if discriminator is None else train.Adversary(discriminator, discriminator_loss),
    )
