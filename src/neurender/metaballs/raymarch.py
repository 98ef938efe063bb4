"""The ray-marched target G-buffers of a metaball scene (thesis listing 5.2, made exact).

Rays through the pixel centres of :func:`neurender.metaballs.scenes.pixel_rays` are
marched by :func:`neurender.metaball.march` between ``MIN_DEPTH`` and ``MAX_DEPTH``, so
depth errors are far below 1e-3 of the depth range. Buffers as
:mod:`neurender.metaballs.gbuffers`: colour = field-weighted blend ``sum c_i f_i / F``;
normal = outward unit normal ``-grad F / |grad F|`` (the thesis's listing returns the
inward gradient).
"""

from __future__ import annotations

import torch

from neurender.metaball import BISECTIONS, MIN_STEP, Scene, march, surface_attributes
from neurender.metaballs.gbuffers import GBuffers, from_hits
from neurender.metaballs.scenes import MAX_DEPTH, MIN_DEPTH, pixel_rays


def render_gbuffers(
    scene: Scene,
    width: int,
    chunk: int = 1 << 14,
    min_step: float = MIN_STEP,
    bisections: int = BISECTIONS,
) -> GBuffers:
    """Ray-march the target G-buffers of a scene at ``width x width``, ``chunk`` rays at a
    time, in the scene's dtype and device; ``min_step`` and ``bisections`` as
    :func:`neurender.metaball.march` (coarser ones make a cheaper, less exact marcher)."""
    dirs = pixel_rays(width, scene.centres.dtype, scene.centres.device).reshape(-1, 3)
    origins = torch.zeros_like(dirs)
    dist = torch.cat(
        [
            march(
                origins[i : i + chunk],
                dirs[i : i + chunk],
                scene,
                MIN_DEPTH,
                MAX_DEPTH,
                min_step,
                bisections,
            )
            for i in range(0, len(dirs), chunk)
        ]
    )
    mask = torch.isfinite(dist)
    colour = torch.zeros(len(dirs), 3, dtype=dirs.dtype, device=dirs.device)
    normal = torch.zeros_like(colour)
    if mask.any():
        colour[mask], n = surface_attributes(dirs[mask] * dist[mask, None], scene)
        normal[mask] = (n + 1) / 2
    return from_hits(dist, colour.T, normal.T, width)
