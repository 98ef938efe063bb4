"""The metaball reference renderer: the ray marcher of :mod:`neurender.metaball`
with a perspective camera, Lambertian shading and ray-marched shadows from a point light.

It is the "other renderer" of paper 4.5: the optimisation only ever sees its images. Its
camera model and shading match :mod:`neurender.simplification.render` (Mitsuba): radiance
``albedo / pi * I * max(0, n . l) / r^2`` where the light is visible, box filter through
``supersample x supersample`` regular sub-pixel rays, black background, coverage in alpha.
"""

from __future__ import annotations

import numpy as np
import torch

from neurender.camera import pixel_rays
from neurender.metaball import Scene, march, surface_attributes
from neurender.simplification.views import View

SHADOW_OFFSET = 0.03  # along the normal, > the marcher's minimum step, << ball radii


def render_implicit(
    scene: Scene, view: View, width: int, supersample: int, intensity: float
) -> np.ndarray:
    """RGBA image ``(W, W, 4)`` float32 of the metaballs seen from ``view``."""
    fine = width * supersample
    dirs = torch.from_numpy(pixel_rays(view, fine).reshape(-1, 3))
    origin = torch.tensor(view.origin, dtype=torch.float64)
    reach = float(np.linalg.norm(view.origin)) + 10.0
    dist = march(origin.expand_as(dirs), dirs, scene, near=0.0, far=reach)
    hit = torch.isfinite(dist)
    rgb = torch.zeros(len(dirs), 3, dtype=torch.float64)
    if hit.any():
        points = origin + dirs[hit] * dist[hit, None]
        albedo, normal = surface_attributes(points, scene)
        to_light = torch.tensor(view.light, dtype=torch.float64) - points
        r = to_light.norm(dim=1)
        l_dir = to_light / r[:, None]
        cos = (normal * l_dir).sum(1).clamp(min=0)
        lit = cos > 0
        start = points[lit] + SHADOW_OFFSET * normal[lit]
        blocked = torch.zeros_like(lit)
        # A crossing before the light (inf when none) shadows the point.
        blocked[lit] = march(start, l_dir[lit], scene, near=0.0, far=float(r.max())) < r[lit]
        shade = intensity * cos / r.square() * (~blocked)
        rgb[hit] = albedo / np.pi * shade[:, None]
    image = torch.cat([rgb, hit[:, None].double()], 1)
    image = image.reshape(width, supersample, width, supersample, 4)
    return image.mean((1, 3)).numpy().astype(np.float32)
