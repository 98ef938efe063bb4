"""The shipped one-graph NDR's inputs (:mod:`neurender.ndr.shipped`), and its ONNX files
(float32 and int8, written by :mod:`neurender.ndr.deploy`) scored on whole test splits as
the evaluation scores the networks.

A sample's graph inputs are remade from the split's stored G-buffers and its map, which
:func:`neurender.ndr.data.sample_scene` draws again from the sample's seed (the map's SH,
prefiltered copies and lights, made once per map as a renderer would). Scores: DSSIM and
L2 of ``I_R``, Reinhard tone-mapped, within the eroded mask, against the clean references
(:func:`neurender.ndr.evaluate.score`).
"""

from __future__ import annotations

import torch

from neurender.ndr import data, environments, prefiltered
from neurender.ndr.buffers import NDRDataset, erode
from neurender.ndr.evaluate import score
from neurender.ndr.model import NDRModel, compose
from neurender.ndr.shipped import gbuffer_groups
from neurender.nn.inference import OnnxNetwork

#: Samples per ONNX Runtime call when a split is scored.
BATCH = 8


@torch.no_grad()
def graph_inputs(
    cfg: dict, model: NDRModel, split: str, index: int, sample: dict[str, torch.Tensor]
) -> tuple[torch.Tensor, ...]:
    """The shipped graph's inputs (:data:`neurender.ndr.shipped.INPUTS`) for sample
    ``index`` of ``split``, float32, batch 1: its G-buffers ``(1, C, H, W)`` from
    ``sample`` (a dataset item, ``(C, H, W)`` per group, its mask as stored: the graph
    shades what a renderer's raw mask covers), then the map's lighting as the data stage
    makes it for ``prefiltered`` (:func:`neurender.ndr.prefiltered.lighting`): its SH
    ``(1, 75)``, irradiance, corner cells and lights."""
    _, env, _, _ = data.sample_scene(cfg, split, index)
    gbuffers = torch.cat([sample[g][None] for g in gbuffer_groups(model)], 1)
    small = environments.resize_latlong(env, cfg["coarse_height"])
    light = prefiltered.lighting(env, small)
    coefficients = light.coefficients.reshape(1, -1)
    return tuple(x.float() for x in (gbuffers, coefficients, *(v[None] for v in light[1:])))


def predict(
    cfg: dict, model: NDRModel, graphs: dict[str, OnnxNetwork], split: str, data_: NDRDataset
) -> dict[str, torch.Tensor]:
    """``I_R`` ``(N, 3, H, W)`` of each of ``graphs`` (name -> a shipped graph of ``model``)
    on every sample of ``split`` (``data_``, read without mask erosion); each batch's inputs
    made once for all of them (the maps' lights padded to the batch's most)."""
    out: dict[str, list[torch.Tensor]] = {name: [] for name in graphs}
    for start in range(0, len(data_), BATCH):
        inputs = [
            graph_inputs(cfg, model, split, i, data_[i])
            for i in range(start, min(start + BATCH, len(data_)))
        ]
        *per_frame, lights = zip(*inputs, strict=True)
        arrays = [torch.cat(parts).numpy() for parts in per_frame]
        arrays.append(prefiltered.stack_lights([k[0] for k in lights]).numpy())
        for name, graph in graphs.items():
            out[name].append(torch.from_numpy(graph(*arrays)))
    return {name: torch.cat(parts) for name, parts in out.items()}


def score_graphs(
    cfg: dict,
    model: NDRModel,
    graphs: dict[str, OnnxNetwork],
    split: str,
    data_: NDRDataset,
    erosion: int,
) -> dict[str, dict[str, torch.Tensor]]:
    """Per graph of ``graphs`` (name -> session), per-sample ``dssim_I_R`` and ``l2_I_R``
    ``(N,)`` on ``split`` (``data_`` read without erosion; scored within its mask eroded by
    ``erosion`` pixels)."""
    b = data_.buffers
    mask = erode(b["mask"], erosion)
    truth = compose(b["I_D"], b["I_S"], b)
    pred = predict(cfg, model, graphs, split, data_)
    return {name: score({"I_R": p}, truth, mask) for name, p in pred.items()}
