"""NDR as one shipped graph: the prefiltered coarse shading and a trained variant's
network in one module, ``(G-buffers, lighting) -> I_R``, exportable to ONNX.

Inputs:

* ``gbuffers`` ``(B, C, H, W)`` float32: the variant's buffer groups other than the
  coarse shading (:func:`gbuffer_groups`: e.g. ``N R D``, then ``A_D A_S`` and ``mask``),
  stacked in that order, as :mod:`neurender.ndr.buffers` stores them;
* the map's lighting, made once per map, not per frame
  (:class:`neurender.ndr.prefiltered.MapLighting`): ``sh`` ``(B, 75)`` its raw 5-band SH
  (coefficient-major, ``k * 3 + channel``; the lighting CSV's values), from which the
  graph computes the network's light features
  (:func:`neurender.ndr.buffers.light_features`); ``irradiance`` ``(B, 18, 3)`` the
  diffuse shading of the map less its bright texels; ``cells`` ``(B, 3, L - 1, h + 1,
  2h + 1, 8)`` the GGX-prefiltered copies of its coarse copy less those texels, as the
  lookup reads them; and ``lights`` ``(B, K, 7)`` those texels as disk lights. ``K`` is
  dynamic (:data:`DYNAMIC_AXES`): a map's own number of lights, 1 to 16 (a batch of maps
  padded by :func:`neurender.ndr.prefiltered.stack_lights`).

The view directions of the fixed camera (:mod:`neurender.ndr.render`) and the split-sum
albedo table are constants of the graph. Output ``I_R`` ``(B, 3, H, W)`` linear HDR.
Coarse shading is zero off the object (``mask``), as in the stored samples. A variant
trained on the importance-sampled shading sees a slightly different input here; one
trained on ``ndr.coarse_shading: prefiltered`` data sees exactly its training input.
"""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from neurender.camera import pixel_rays
from neurender.ndr import prefiltered
from neurender.ndr.buffers import channel_count
from neurender.ndr.model import NDRModel
from neurender.ndr.render import camera
from neurender.ndr.variants import SHADING_GROUPS

#: The graph's input names (see the module docstring).
INPUTS = ("gbuffers", "sh", "irradiance", "cells", "lights")
#: The graph's axes besides the batch that are dynamic: a map's number of lights.
DYNAMIC_AXES = {"lights": {1: "lights"}}


def gbuffer_groups(model: NDRModel) -> tuple[str, ...]:
    """The buffer groups the graph takes: the network's inputs but the coarse shading,
    then the albedos and the mask."""
    groups = tuple(g for g in model.variant.inputs if g not in SHADING_GROUPS)
    return groups + tuple(g for g in ("N", "R", "A_D", "A_S", "mask") if g not in groups)


def light_features(coefficients: torch.Tensor) -> torch.Tensor:
    """:func:`neurender.ndr.buffers.light_features` in torch: ``sign(c) log(1 + |c|)``."""
    return torch.sign(coefficients) * torch.log1p(coefficients.abs())


class CoarseShading(nn.Module):
    """``(gbuffers, irradiance, cells, lights) -> (S_D, S_S)`` each ``(B, 3, H, W)``: the
    prefiltered coarse shading of a fixed camera's image (``distance``, ``fov`` in
    degrees, ``width`` px)."""

    def __init__(self, groups: tuple[str, ...], distance: float, fov: float, width: int):
        super().__init__()
        self.groups = groups
        self.counts = [channel_count(g) for g in groups]
        view = -pixel_rays(camera(distance, fov), width).reshape(-1, 3).T  # (3, HW)
        self.register_buffer("view_dirs", torch.from_numpy(view.astype(np.float32)))
        self.register_buffer("table", prefiltered.albedo_table().float())

    def forward(
        self,
        gbuffers: torch.Tensor,
        irradiance: torch.Tensor,
        cells: torch.Tensor,
        lights: torch.Tensor,
    ) -> tuple[torch.Tensor, torch.Tensor]:
        g = dict(zip(self.groups, torch.split(gbuffers, self.counts, 1), strict=True))
        b, _, h, w = gbuffers.shape
        normals = g["N"].flatten(2)  # (B, 3, HW): channels first, as specular_shading wants
        roughness = g["R"].flatten(1)
        alpha = roughness * roughness
        view = self.view_dirs.expand(b, -1, -1)
        s_d = prefiltered.diffuse_shading(normals, irradiance, lights)
        s_s = prefiltered.specular_shading(normals, view, alpha, cells, self.table, lights)
        mask = g["mask"]
        return s_d.reshape(b, 3, h, w) * mask, s_s.reshape(b, 3, h, w) * mask


class ShadingPart(nn.Module):
    """The shading alone, ``S_D`` and ``S_S`` stacked ``(B, 6, H, W)`` (timed as a part)."""

    def __init__(self, shading: CoarseShading):
        super().__init__()
        self.shading = shading

    def forward(self, gbuffers, sh, irradiance, cells, lights) -> torch.Tensor:
        return torch.cat(self.shading(gbuffers, irradiance, cells, lights), 1)


class ShippedNDR(nn.Module):
    """``(gbuffers, sh, irradiance, cells, lights) -> I_R``: coarse shading and one trained
    variant (see the module docstring); the camera and width are the data's
    (``ndr.camera_distance``, ``ndr.fov``, ``ndr.width``)."""

    def __init__(self, model: NDRModel, distance: float, fov: float, width: int):
        super().__init__()
        self.model = model.eval()
        self.shading = CoarseShading(gbuffer_groups(model), distance, fov, width)

    def batch(self, gbuffers, sh, irradiance, cells, lights) -> dict[str, torch.Tensor]:
        """The model's batch dict: the G-buffers, the shading, the light features."""
        s_d, s_s = self.shading(gbuffers, irradiance, cells, lights)
        split = torch.split(gbuffers, self.shading.counts, 1)
        batch = dict(zip(self.shading.groups, split, strict=True))
        return {**batch, "S_D": s_d, "S_S": s_s, "light": light_features(sh)}

    def forward(self, gbuffers, sh, irradiance, cells, lights) -> torch.Tensor:
        return self.model(self.batch(gbuffers, sh, irradiance, cells, lights))["I_R"]
