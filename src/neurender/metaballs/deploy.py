"""Metaball generators as the files a renderer ships: ONNX graphs from the network's
inputs in [0, 1] (:func:`neurender.metaballs.model.network_inputs`) to the G-buffer stack
``(B, 7, W, W)`` in [0, 1] (:mod:`neurender.metaballs.gbuffers`), the [-1, 1] mapping of
pix2pix inside.

A GAN-trained generator normalises with each image's own statistics
(:class:`neurender.metaballs.renderer.MetaballRenderer`): for a batch of one image that
is instance normalisation with the batch norm's scale and shift, which is what its graph
uses, so a batch of several images gives each image's own result.
"""

from __future__ import annotations

import copy

import torch
from torch import nn

from neurender.deployment import measure
from neurender.metaball import Scene
from neurender.metaballs.renderer import MetaballRenderer

#: Scenes an export is checked on: the first of a split (the first twice if it has one).
EXAMPLES = 2


def per_image_normalisation(model: nn.Module) -> nn.Module:
    """A copy of ``model`` with every batch norm replaced by instance normalisation with
    the same scale, shift and epsilon (batch statistics of one image)."""
    model = copy.deepcopy(model)
    for parent in list(model.modules()):
        for name, child in parent.named_children():
            if isinstance(child, nn.BatchNorm2d):
                norm = nn.InstanceNorm2d(child.num_features, eps=child.eps, affine=True)
                norm.weight.data.copy_(child.weight.data)
                norm.bias.data.copy_(child.bias.data)
                setattr(parent, name, norm)
    return model


class GeneratorGraph(nn.Module):
    """``(B, C, W, W)`` inputs in [0, 1] -> ``(B, 7, W, W)`` G-buffers in [0, 1]."""

    def __init__(self, generator: nn.Module, image_statistics: bool):
        super().__init__()
        self.generator = (
            per_image_normalisation(generator) if image_statistics else generator
        ).eval()

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return ((self.generator(x * 2 - 1) + 1) / 2).clamp(0, 1)


def example_inputs(renderer: MetaballRenderer, scenes: dict[int, Scene]) -> torch.Tensor:
    """The renderer's inputs ``(EXAMPLES, C, W, W)`` in [0, 1] for the first
    :data:`EXAMPLES` scenes by example number (repeated if there are fewer): what an export
    is checked on."""
    first = [scenes[k] for k in sorted(scenes)][:EXAMPLES]
    if not first:
        raise ValueError("no scenes to check an export on")
    return torch.stack([renderer.inputs(first[i % len(first)]) for i in range(EXAMPLES)]).cpu()


def deploy_generator(
    variant: str, renderer: MetaballRenderer, inputs: torch.Tensor, onnx_out: str, threads: int
) -> dict:
    """The deployment row of one trained generator (:func:`neurender.deployment.measure`):
    its graph exported, checked on ``inputs`` ``(B >= 2, C, W, W)`` and timed by both
    engines on one image."""
    graph = GeneratorGraph(renderer.model.cpu(), renderer.image_statistics)
    return measure("metaballs", variant, graph, (inputs,), onnx_out, threads, atol=1e-3)
