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
from neurender.metaballs.grid import build_grid
from neurender.metaballs.scenes import MAX_DEPTH, MIN_DEPTH, pixel_rays


def render_gbuffers(
    scene: Scene,
    width: int,
    chunk: int = 1 << 14,
    min_step: float | None = None,
    bisections: int = BISECTIONS,
) -> GBuffers:
    """Ray-march the target G-buffers of a scene at ``width x width``, ``chunk`` rays at a
    time, in the scene's dtype and device; ``min_step`` and ``bisections`` as
    :func:`neurender.metaball.march` (coarser ones make a cheaper, less exact marcher).

    A kernel of finite support is marched through cell lists
    (:meth:`neurender.metaballs.grid.BallGrid.march`, its rays visiting only the cells they
    cross; ``min_step`` then defaults to the grid's share of the smallest radius); the
    inverse square sums every ball at every step."""
    dirs = pixel_rays(width, scene.centres.dtype, scene.centres.device).reshape(-1, 3)
    origins = torch.zeros_like(dirs)
    if scene.kernel.finite:
        grid = build_grid(scene)

        def trace(o, d):
            return grid.march(o, d, MIN_DEPTH, MAX_DEPTH, min_step, bisections)

        shade = grid.surface_attributes
    else:
        min_step = MIN_STEP if min_step is None else min_step

        def trace(o, d):
            return march(o, d, scene, MIN_DEPTH, MAX_DEPTH, min_step, bisections)

        def shade(points):
            return surface_attributes(points, scene)

    dist = torch.cat(
        [trace(origins[i : i + chunk], dirs[i : i + chunk]) for i in range(0, len(dirs), chunk)]
    )
    mask = torch.isfinite(dist)
    colour = torch.zeros(len(dirs), 3, dtype=dirs.dtype, device=dirs.device)
    normal = torch.zeros_like(colour)
    hits = mask.nonzero().squeeze(1)
    # Cell lists' chunks bound the point-ball pairs in memory; the inverse square's rows
    # stay one batch (its numbers as they were).
    step = chunk if scene.kernel.finite else max(len(hits), 1)
    for i in range(0, len(hits), step):
        rows = hits[i : i + step]
        colour[rows], n = shade(dirs[rows] * dist[rows, None])
        normal[rows] = (n + 1) / 2
    return from_hits(dist, colour.T, normal.T, width)
