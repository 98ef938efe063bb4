"""Networks for image-space metaballs: the thesis's pix2pix (4.2, 5.3) and our residual model.

Tensors are in [-1, 1] as the thesis does. Inputs ``(B, C, W, W)``: the circle image (4:
colour, centre depth), and for ``sphere_residual`` also the inflated-sphere impostors (7:
:func:`neurender.metaballs.inputs.inflated_spheres`). Outputs ``(B, 7, W, W)`` = colour (3),
depth (1), encoded normal (3).

Variants:
* ``pix2pix``: the thesis; circles in, loss ``gan_weight`` x BCE(D(x, G(x)), real) +
  ``l1_weight`` x L1(G(x), y) with a PatchGAN conditioned on the input.
* ``l1only``: the same without the GAN term (ablation).
* ``sphere_residual`` (ours): circles and impostors in; the U-Net's output (no tanh, last
  layer zero-initialised) is added to the impostors, so training starts from the
  inflated-sphere prior and learns only the blend. L1 only.
"""

from __future__ import annotations

import logging
import math
from pathlib import Path

import numpy as np
import torch
from torch import nn
from torch.utils.data import Dataset

from neurender import io, train
from neurender.metaball import Scene
from neurender.metaballs import ab, inputs
from neurender.metaballs.data import read_scenes
from neurender.metaballs.evaluate import NORMAL_FOREGROUND
from neurender.nn.pix2pix import NLayerDiscriminator, UnetGenerator, init_weights

log = logging.getLogger(__name__)

CIRCLE_CHANNELS = 4
OUTPUT_CHANNELS = 7
VARIANTS = ("pix2pix", "l1only", "sphere_residual")


def uses_spheres(variant: str) -> bool:
    """Whether a variant's input carries the inflated-sphere impostors."""
    if variant not in VARIANTS:
        raise ValueError(f"metaballs model variant {variant!r}: expected one of {VARIANTS}")
    return variant == "sphere_residual"


def input_channels(variant: str) -> int:
    """Channels of a variant's input: 4 circle channels, plus 7 impostor channels."""
    return CIRCLE_CHANNELS + (OUTPUT_CHANNELS if uses_spheres(variant) else 0)


def network_inputs(
    scene: Scene | None, width: int, variant: str, circles: torch.Tensor | None = None
) -> torch.Tensor:
    """A variant's input ``(C, W, W)`` in [0, 1] for a scene.

    Args:
        scene: the balls; only needed to draw what ``circles`` does not give.
        circles: the ``(4, W, W)`` circle image when already drawn (e.g. read from an AB
            image); drawn from the scene otherwise.
    """
    if circles is None:
        circles = inputs.draw_inputs(scene, width)
    circles = circles.float()
    if not uses_spheres(variant):
        return circles
    return torch.cat([circles, inputs.inflated_spheres(scene, width).stack()])


def flip(x: torch.Tensor, y: torch.Tensor, horizontal: bool, vertical: bool, spheres: bool):
    """Mirror an ``(input, target)`` pair in [-1, 1] across the image's vertical and/or
    horizontal axis: the camera is symmetric, so this is the mirrored scene's example.

    Mirroring negates the normals' x (horizontal) or y (vertical) component on the surface;
    the background's normal stays 0 (encoded -1).
    """

    def mirror_normals(normal: torch.Tensor, axis: int) -> torch.Tensor:
        foreground = (normal + 1).sum(0) / 2 > NORMAL_FOREGROUND  # on encoded normals
        out = normal.clone()
        out[axis] = torch.where(foreground, -normal[axis], normal[axis])
        return out

    for flag, dim, axis in ((horizontal, -1, 0), (vertical, -2, 1)):
        if not flag:
            continue
        x, y = x.flip(dim), y.flip(dim)
        y = torch.cat([y[:4], mirror_normals(y[4:7], axis)])
        if spheres:
            x = torch.cat([x[:8], mirror_normals(x[8:11], axis)])
    return x, y


class ABDataset(Dataset):
    """AB examples of a split, kept in memory as uint8 ``(N, W, 3W, 4)``.

    Items are ``(input (C, W, W), target (7, W, W))`` float32 in [-1, 1]. With ``flips`` the
    dataset is four times as long: item ``k`` is example ``k // 4`` mirrored by the bits of
    ``k % 4`` (horizontal, vertical), so an epoch sees every example in all four mirrorings.
    """

    def __init__(
        self,
        folder: str | Path,
        manifest: str | Path,
        balls: str | Path,
        variant: str,
        flips: bool = False,
    ):
        table = io.read_csv(manifest, ["example", "file"]).sort_values("example")
        self.examples = table["example"].astype(int).tolist()
        self.images = np.stack([io.read_png(Path(folder) / f) for f in table["file"]])
        if self.images.dtype != np.uint8 or self.images.shape[-1] != 4:
            raise ValueError(
                f"{folder}: AB examples must be 8-bit RGBA, "
                f"got {self.images.dtype} {self.images.shape}"
            )
        self.variant = variant
        self.spheres = uses_spheres(variant)
        self.scenes = read_scenes(balls) if self.spheres else {}
        missing = [e for e in self.examples if self.spheres and e not in self.scenes]
        if missing:
            raise ValueError(f"{balls}: no balls for examples {missing[:5]} of {manifest}")
        self.copies = 4 if flips else 1

    def __len__(self) -> int:
        return len(self.images) * self.copies

    def __getitem__(self, k: int) -> tuple[torch.Tensor, torch.Tensor]:
        i, mirroring = divmod(k, self.copies)
        parts = ab.unpack(self.images[i])
        width = parts["inputs"].shape[-1]
        x = network_inputs(
            self.scenes.get(self.examples[i]), width, self.variant, circles=parts["inputs"]
        )
        y = torch.cat([parts["colour"], parts["depth"], parts["normal"]])
        return flip(x * 2 - 1, y * 2 - 1, bool(mirroring & 1), bool(mirroring & 2), self.spheres)


class PriorResidual(nn.Module):
    """``prior + correction``: the prior is the input's last 7 channels, the correction a
    U-Net without tanh whose last layer starts at zero. ``(B, 11, W, W) -> (B, 7, W, W)``."""

    def __init__(self, unet: UnetGenerator):
        super().__init__()
        self.unet = unet
        # The outermost up-convolution is the last transposed convolution registered.
        head = [m for m in unet.modules() if isinstance(m, nn.ConvTranspose2d)][-1]
        nn.init.zeros_(head.weight)
        nn.init.zeros_(head.bias)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return x[:, -OUTPUT_CHANNELS:] + self.unet(x)


def build_generator(width: int, ngf: int, variant: str) -> nn.Module:
    """U-Net with log2(W) downsamplings (1 x 1 bottleneck), pix2pix initialisation."""
    downs = int(round(math.log2(width)))
    if 2**downs != width:
        raise ValueError(f"metaballs.width={width}: the pix2pix U-Net needs a power of two")
    spheres = uses_spheres(variant)
    unet = init_weights(
        UnetGenerator(input_channels(variant), OUTPUT_CHANNELS, downs, ngf, output_tanh=not spheres)
    )
    return PriorResidual(unet) if spheres else unet


def build_discriminator(ndf: int, variant: str) -> NLayerDiscriminator:
    """PatchGAN conditioned on the input: 4 + 7 = 11 channels for the thesis's pix2pix."""
    return init_weights(NLayerDiscriminator(input_channels(variant) + OUTPUT_CHANNELS, ndf))


def train_generator(
    files: dict[str, str], cfg: dict, threads: int, checkpoint: str, log_csv: str
) -> None:
    """Train one variant's generator (and, when ``gan_weight > 0``, its PatchGAN).

    Args:
        files: ``train_dir, train_manifest, train_balls`` and the same for ``val``.
        cfg: ``variant, seed, width, ngf, ndf, gan_weight, l1_weight, flips`` and the
            training keys of :class:`neurender.train.TrainConfig`.
    """
    torch.manual_seed(cfg["seed"])
    variant = cfg["variant"]
    generator = build_generator(cfg["width"], cfg["ngf"], variant)
    gan_weight, l1_weight = cfg["gan_weight"], cfg["l1_weight"]
    bce = torch.nn.BCEWithLogitsLoss()
    discriminator = build_discriminator(cfg["ndf"], variant) if gan_weight > 0 else None

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

    def dataset(split: str, flips: bool) -> ABDataset:
        return ABDataset(
            files[f"{split}_dir"],
            files[f"{split}_manifest"],
            files[f"{split}_balls"],
            variant,
            flips=flips,
        )

    config = train.TrainConfig.from_stage(cfg, threads, betas=(0.5, 0.999))
    train.fit(
        generator,
        dataset("train", cfg["flips"]),
        dataset("val", False),
        generator_loss,
        config,
        checkpoint,
        log_csv,
        extra_state={
            "width": cfg["width"],
            "ngf": cfg["ngf"],
            "gan_weight": gan_weight,
            "variant": variant,
        },
        adversary=None
        if discriminator is None
        else train.Adversary(discriminator, discriminator_loss),
    )


class MetaballRenderer:
    """A trained generator for inference: :meth:`inputs` builds its input from a scene,
    calling it gives the G-buffers.

    A GAN-trained generator normalises batch norm with the statistics of the image being
    rendered, as in the pix2pix authors' test code: its running averages failed (held-out
    IoU 0.27 against 0.73). L1-trained ones use the running averages (the residual model
    scored IoU 0.81 with per-image statistics, 0.88 with running averages). Dropout is off.
    """

    def __init__(self, checkpoint: str | Path, device: str = "auto", threads: int = 1):
        state = train.load_checkpoint(checkpoint)
        extra = state["extra"]
        self.device = train.resolve_device(device, threads)
        self.variant = extra["variant"]
        self.width = extra["width"]
        self.model = build_generator(self.width, extra["ngf"], self.variant)
        self.model.load_state_dict(state["model"])
        self.model.to(self.device).eval()
        self.image_statistics = extra["gan_weight"] > 0
        if self.image_statistics:
            for module in self.model.modules():
                if isinstance(module, torch.nn.BatchNorm2d):
                    module.train()

    def inputs(self, scene: Scene, circles: torch.Tensor | None = None) -> torch.Tensor:
        """The ``(C, W, W)`` input in [0, 1] (see :func:`network_inputs`), drawn on the
        renderer's device (on a GPU, drawing on the CPU would cost more than the network)."""
        on_device = Scene(*(t.to(self.device) for t in (scene.centres, scene.radii, scene.colours)))
        if circles is not None:
            circles = circles.to(self.device)
        return network_inputs(on_device, self.width, self.variant, circles)

    @torch.no_grad()
    def __call__(self, x: torch.Tensor) -> torch.Tensor:
        """Inputs ``(B, C, W, W)`` in [0, 1] to G-buffers ``(B, 7, W, W)`` in [0, 1]."""
        x = x.to(self.device, torch.float32) * 2 - 1
        if self.image_statistics:  # one image per pass: batch statistics must not mix images
            out = torch.cat([self.model(x[i : i + 1]) for i in range(len(x))])
        else:
            out = self.model(x)
        return ((out + 1) / 2).clamp(0, 1).cpu()
