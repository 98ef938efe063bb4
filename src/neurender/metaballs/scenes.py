"""Metaball scenes and the camera of the image-space metaballs thesis (chapter 5.2).

View space: camera at the origin looking along +z, x right, y up. A pixel's ray direction
is ``normalize((s tan(fov), t tan(fov), 1))`` with ``s, t`` in [-1, 1] across the image
(listing 5.2: ``FOV`` = 30 degrees at the image edge). Image row 0 is the top (t = 1).
Depth is the distance along the ray, normalised to [0, 1] between ``MIN_DEPTH`` and
``MAX_DEPTH`` (background = 1). The balls' field and surface (eq. 5.1) are those of
:mod:`neurender.metaball`.
"""

from __future__ import annotations

import math

import torch

from neurender.metaball import Scene

FOV_DEG = 30.0
MIN_DEPTH = 7.0
MAX_DEPTH = 25.0


def sample_scene(
    count: int, radius_range: tuple[float, float], generator: torch.Generator, margin: float = 1.0
) -> Scene:
    """Random balls inside the view frustum, centre depths in ``[MIN + margin, MAX - margin]``.

    Args:
        count: number of balls.
        radius_range: (min, max) of ``r``.
        generator: torch RNG (the only source of randomness).
    """
    u = torch.rand(count, 5, generator=generator, dtype=torch.float64)
    depth = MIN_DEPTH + margin + u[:, 0] * (MAX_DEPTH - MIN_DEPTH - 2 * margin)
    st = (u[:, 1:3] * 2 - 1) * 0.9
    dirs = torch.cat(
        [st * math.tan(math.radians(FOV_DEG)), torch.ones(count, 1, dtype=torch.float64)], 1
    )
    centres = depth[:, None] * dirs / dirs.norm(dim=1, keepdim=True)
    radii = radius_range[0] + u[:, 3] * (radius_range[1] - radius_range[0])
    colours = torch.rand(count, 3, generator=generator, dtype=torch.float64)
    return Scene(centres, radii, colours)


def pixel_rays(width: int, dtype=torch.float64, device=None) -> torch.Tensor:
    """Unit ray directions ``(W, W, 3)`` through pixel centres, row 0 at the top."""
    c = (torch.arange(width, dtype=dtype, device=device) + 0.5) / width * 2 - 1
    t, s = torch.meshgrid(-c, c, indexing="ij")
    tan = math.tan(math.radians(FOV_DEG))
    d = torch.stack([s * tan, t * tan, torch.ones_like(s)], -1)
    return d / d.norm(dim=-1, keepdim=True)


def project(points: torch.Tensor, width: int) -> torch.Tensor:
    """Pixel coordinates ``(N, 2)`` (column, row; continuous, 0 at the top-left corner)."""
    tan = math.tan(math.radians(FOV_DEG))
    s = points[:, 0] / points[:, 2] / tan
    t = points[:, 1] / points[:, 2] / tan
    return torch.stack([(s + 1) / 2 * width, (1 - t) / 2 * width], 1)


def normalised_depth(distance: torch.Tensor) -> torch.Tensor:
    """Distance along the ray mapped to [0, 1] between MIN_DEPTH and MAX_DEPTH."""
    return ((distance - MIN_DEPTH) / (MAX_DEPTH - MIN_DEPTH)).clamp(0, 1)
