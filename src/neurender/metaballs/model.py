"""pix2pix for image-space metaballs (thesis 4.2, 5.3): circles in, G-buffers out.

Tensors are in [-1, 1] as the thesis does: input ``(B, 4, W, W)`` (circle colour, centre
depth), output ``(B, 7, W, W)`` = target colour (3), depth (1), encoded normal (3).
Generator loss = ``gan_weight`` x BCE(D(x, G(x)), real) + ``l1_weight`` x L1(G(x), y);
``gan_weight = 0`` trains the L1-only ablation without a discriminator.
"""

from __future__ import annotations

import logging
import math
from pathlib import Path

import numpy as np
import torch
from torch.utils.data import Dataset

from neurender import io, train
from neurender.metaballs import ab
from neurender.nn.pix2pix import NLayerDiscriminator, UnetGenerator, init_weights

log = logging.getLogger(__name__)

INPUT_CHANNELS = 4
OUTPUT_CHANNELS = 7


class ABDataset(Dataset):
    """AB examples of a split, kept in memory as uint8 ``(N, W, 3W, 4)``.

    Items are ``(input (4, W, W), target (7, W, W))`` float32 in [-1, 1].
    """

    def __init__(self, folder: str | Path, manifest: str | Path):
        files = io.read_csv(manifest, ["example", "file"]).sort_values("example")["file"]
        self.images = np.stack([io.read_png(Path(folder) / f) for f in files])
        if self.images.dtype != np.uint8 or self.images.shape[-1] != 4:
            raise ValueError(
                f"{folder}: AB examples must be 8-bit RGBA, "
                f"got {self.images.dtype} {self.images.shape}"
            )

    def __len__(self) -> int:
        return len(self.images)

    def __getitem__(self, i: int) -> tuple[torch.Tensor, torch.Tensor]:
        parts = ab.unpack(self.images[i])
        x = parts["inputs"]
        y = torch.cat([parts["colour"], parts["depth"], parts["normal"]])
        return x * 2 - 1, y * 2 - 1


def build_generator(width: int, ngf: int) -> UnetGenerator:
    """U-Net with log2(W) downsamplings (1 x 1 bottleneck), pix2pix initialisation."""
    downs = int(round(math.log2(width)))
    if 2**downs != width:
        raise ValueError(f"metaballs.width={width}: the pix2pix U-Net needs a power of two")
    return init_weights(UnetGenerator(INPUT_CHANNELS, OUTPUT_CHANNELS, downs, ngf))


def build_discriminator(ndf: int) -> NLayerDiscriminator:
    """PatchGAN conditioned on the input: 4 + 7 = 11 channels."""
    return init_weights(NLayerDiscriminator(INPUT_CHANNELS + OUTPUT_CHANNELS, ndf))


def train_pix2pix(
    train_dir: str,
    train_manifest: str,
    val_dir: str,
    val_manifest: str,
    cfg: dict,
    threads: int,
    checkpoint: str,
    log_csv: str,
) -> None:
    """Train the generator (and, when ``gan_weight > 0``, the PatchGAN) with the shared loop."""
    torch.manual_seed(cfg["seed"])
    generator = build_generator(cfg["width"], cfg["ngf"])
    gan_weight, l1_weight = cfg["gan_weight"], cfg["l1_weight"]
    bce = torch.nn.BCEWithLogitsLoss()
    discriminator = build_discriminator(cfg["ndf"]) if gan_weight > 0 else None

    def generator_loss(model, batch):
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

    def discriminator_loss(module, batch, fake):
        x, y = batch
        real = module(torch.cat([x, y], 1))
        faked = module(torch.cat([x, fake], 1))
        loss = 0.5 * (bce(real, torch.ones_like(real)) + bce(faked, torch.zeros_like(faked)))
        return loss, {}

    config = train.TrainConfig.from_stage(cfg, threads, betas=(0.5, 0.999))
    train.fit(
        generator,
        ABDataset(train_dir, train_manifest),
        ABDataset(val_dir, val_manifest),
        generator_loss,
        config,
        checkpoint,
        log_csv,
        extra_state={"width": cfg["width"], "ngf": cfg["ngf"], "gan_weight": gan_weight},
        adversary=None
        if discriminator is None
        else train.Adversary(discriminator, discriminator_loss),
    )


class Pix2PixRenderer:
    """A trained generator for inference, one image at a time.

    As in the pix2pix authors' test code, batch norm normalises with the statistics of the
    image being rendered: the running averages failed for the GAN-trained generator
    (held-out IoU 0.27 against 0.73) and made no difference to the L1-only one.
    Dropout is off.
    """

    def __init__(self, checkpoint: str | Path, device: str = "auto", threads: int = 1):
        state = train.load_checkpoint(checkpoint)
        extra = state["extra"]
        self.device = train.resolve_device(device, threads)
        self.model = build_generator(extra["width"], extra["ngf"])
        self.model.load_state_dict(state["model"])
        self.model.to(self.device).eval()
        for module in self.model.modules():
            if isinstance(module, torch.nn.BatchNorm2d):
                module.train()

    @torch.no_grad()
    def __call__(self, inputs: torch.Tensor) -> torch.Tensor:
        """Inputs ``(B, 4, W, W)`` in [0, 1] to G-buffers ``(B, 7, W, W)`` in [0, 1]."""
        x = inputs.to(self.device, torch.float32) * 2 - 1
        # One image per forward pass: batch statistics must not mix images.
        out = torch.cat([self.model(x[i : i + 1]) for i in range(len(x))])
        return ((out + 1) / 2).clamp(0, 1).cpu()
