"""Networks for image-space metaballs: the thesis's pix2pix (4.2, 5.3) and our residual model.

Tensors are in [-1, 1] as the thesis does. Inputs ``(B, C, W, W)``: the circle image (4:
colour, centre depth), and for ``sphere_residual`` also the inflated-sphere impostors (a
G-buffer stack, :func:`neurender.metaballs.inputs.inflated_spheres`). Outputs
``(B, 7, W, W)``: G-buffer stacks (:mod:`neurender.metaballs.gbuffers`).

Variants (:data:`neurender.metaballs.VARIANTS`):
* ``pix2pix``: the thesis; circles in, loss ``gan_weight`` x BCE(D(x, G(x)), real) +
  ``l1_weight`` x L1(G(x), y) with a PatchGAN conditioned on the input.
* ``l1only``: the same without the GAN term (ablation).
* ``sphere_residual`` (ours): circles and impostors in; the U-Net's output (no tanh, last
  layer zero-initialised) is added to the impostors, so training starts from the
  inflated-sphere prior and learns only the blend. L1 only.
"""

from __future__ import annotations

import math

import torch
from torch import nn

from neurender.metaball import Scene
from neurender.metaballs import VARIANTS, gbuffers, inputs
from neurender.nn.pix2pix import NLayerDiscriminator, UnetGenerator, init_weights

CIRCLE_CHANNELS = 4
OUTPUT_CHANNELS = gbuffers.CHANNELS


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
    """A variant's input ``(C, W, W)`` float32 in [0, 1] for a scene: the circles, then
    (``sphere_residual``) the impostors' G-buffer stack.

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


class PriorResidual(nn.Module):
    """``prior + correction``: the prior is the input's last 7 channels (the impostors), the
    correction a U-Net without tanh whose last layer starts at zero.
    ``(B, 11, W, W) -> (B, 7, W, W)``."""

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
