"""NDR networks as the files a renderer ships: each trained variant with its tone mapping,
light encoding and image composition in one ONNX graph, and NDR as one shipped graph with
its coarse shading, in float32 and in int8.

A variant's graph inputs: ``buffers`` ``(B, C, H, W)`` float32, the raw (linear, HDR where
they are) buffer groups of :func:`graph_groups` stacked in that order, and ``light``
``(B, 75)`` the map's SH features (:func:`neurender.ndr.buffers.light_features`). Output:
``I_R`` ``(B, 3, H, W)`` linear HDR radiance. The graph is exactly :class:`NDRModel`'s
forward.

The shipped one-graph NDR (:mod:`neurender.ndr.shipped`: G-buffers and the map's lighting
in, ``I_R`` out) is checked against PyTorch on the first test sample; its int8 form is the
float32 file with its convolutions (and the ReLUs and upsamplings between them) in int8
(:func:`neurender.nn.inference.quantize_convolutions`), their activation ranges calibrated
on the first :data:`~neurender.ndr.CALIBRATION_SAMPLES` training samples, never on a test
sample. A sample's graph inputs are remade from its stored G-buffers and its map, drawn
again from the sample's seed (:func:`neurender.ndr.graph_scores.graph_inputs`).
"""

from __future__ import annotations

import torch
from torch import nn

from neurender.deployment import measure
from neurender.ndr import CALIBRATION_SAMPLES
from neurender.ndr.buffers import NDRDataset, channel_count
from neurender.ndr.graph_scores import graph_inputs as shipped_inputs
from neurender.ndr.model import NDRModel
from neurender.ndr.shipped import DYNAMIC_AXES, ShippedNDR
from neurender.ndr.shipped import INPUTS as SHIPPED_INPUTS
from neurender.nn.inference import export_onnx, quantize_convolutions

#: Samples an export is checked on: the first of a split (the first twice if it has one).
EXAMPLES = 2
#: The graph's input names (see the module docstring).
INPUTS = ("buffers", "light")


def graph_groups(model: NDRModel) -> tuple[str, ...]:
    """The buffer groups a variant's graph takes: its network inputs, then what its prior
    and the composition of ``I_R`` need (coarse shading, albedos)."""
    extra = ("S_D", "S_S") if model.residual else ()
    groups = tuple(model.variant.inputs)
    return groups + tuple(g for g in (*extra, "A_D", "A_S") if g not in groups)


class NDRGraph(nn.Module):
    """``(buffers, light) -> I_R`` for one trained variant (see the module docstring)."""

    def __init__(self, model: NDRModel):
        super().__init__()
        self.model = model.eval()
        self.groups = graph_groups(model)
        self.counts = [channel_count(g) for g in self.groups]

    def forward(self, buffers: torch.Tensor, light: torch.Tensor) -> torch.Tensor:
        batch = dict(zip(self.groups, torch.split(buffers, self.counts, 1), strict=True))
        batch["light"] = light
        return self.model(batch)["I_R"]


def graph_inputs(model: NDRModel, batch: dict[str, torch.Tensor]) -> tuple[torch.Tensor, ...]:
    """A dataset batch as the graph's ``(buffers, light)``."""
    return torch.cat([batch[g] for g in graph_groups(model)], 1), batch["light"]


def example_batch(data: NDRDataset) -> dict[str, torch.Tensor]:
    """The first :data:`EXAMPLES` samples of a split as one batch (repeated if the split
    has fewer): what an export is checked on."""
    index = torch.arange(EXAMPLES) % len(data)
    return {"light": data.light[index], **{g: v[index] for g, v in data.buffers.items()}}


def deploy_variant(
    variant: str, model: NDRModel, batch: dict[str, torch.Tensor], onnx_out: str, threads: int
) -> dict:
    """The deployment row of one trained variant (:func:`neurender.deployment.measure`):
    its graph exported, checked on ``batch`` (at least two samples) and timed by both
    engines on its first sample."""
    graph = NDRGraph(model.cpu())
    inputs = graph_inputs(model, batch)
    # I_R is linear HDR radiance (above 100 where a sun reflects): the check scales with it.
    return measure(
        "ndr", variant, graph, inputs, onnx_out, threads, atol=1e-3, rtol=1e-4, input_names=INPUTS
    )


def export_shipped(cfg: dict, model: NDRModel, test: NDRDataset, path: str) -> float:
    """Write NDR (``model``, on the CPU) with the prefiltered coarse shading of the data's
    camera and width (``cfg``'s ``camera_distance``, ``fov``, ``width``) as one ONNX graph
    (:class:`neurender.ndr.shipped.ShippedNDR`), checked against PyTorch on the first
    sample of the test split ``test`` (its map drawn again from ``cfg``'s scene keys, sent
    as a batch of two copies); the largest difference."""
    shipped = ShippedNDR(model, cfg["camera_distance"], cfg["fov"], cfg["width"])
    inputs = shipped_inputs(cfg, model, "test", 0, test[0])
    pair = tuple(torch.cat([t, t]) for t in inputs)  # a batch of one would fix the batch axis
    # I_R is linear HDR radiance: the check scales with it, as the variants'.
    return export_onnx(
        shipped,
        pair,
        path,
        atol=1e-3,
        rtol=1e-4,
        input_names=SHIPPED_INPUTS,
        dynamic_axes=DYNAMIC_AXES,
    )


def export_shipped_int8(
    cfg: dict, model: NDRModel, train: NDRDataset, source: str, path: str
) -> None:
    """The float32 shipped graph ``source`` (of ``model``) with its convolutions int8,
    calibrated on the first :data:`~neurender.ndr.CALIBRATION_SAMPLES` samples of the
    training split ``train`` (fewer where it has fewer; see the module docstring), written
    to ``path``."""
    feeds = []
    for i in range(min(CALIBRATION_SAMPLES, len(train))):
        inputs = shipped_inputs(cfg, model, "train", i, train[i])
        feeds.append({name: x.numpy() for name, x in zip(SHIPPED_INPUTS, inputs, strict=True)})
    quantize_convolutions(source, path, feeds)
