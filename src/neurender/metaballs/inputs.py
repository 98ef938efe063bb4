"""What a network sees of a metaball scene: circle images (thesis 4.1.1, listing 5.1) and,
for our residual model, sphere impostors.

Circles: each ball becomes the outline of a circle at its projected centre: a camera-facing
square billboard of world size ``2 r`` at the ball's centre, with the ring ``0.45 < |uv -
0.5| < 0.5`` of the quad filled, i.e. between 0.9 and 1.0 of the projected radius. RGB = the
ball's colour; A = the normalised depth of the centre. Nearer circles are drawn over farther
ones. Background: RGB 0, A 1 (far).

Sphere impostors: every ball ray-traced as a sphere, the nearest hit per pixel, as G-buffers
in the layout of :mod:`neurender.metaballs.raymarch`. Both cost one test per ball and pixel
(a billboard per ball on a GPU), never a march through the field.
"""

from __future__ import annotations

import math

import torch

from neurender.metaballs.raymarch import GBuffers
from neurender.metaballs.scenes import (
    FOV_DEG,
    MAX_DEPTH,
    THRESHOLD,
    Scene,
    normalised_depth,
    pixel_rays,
    project,
)

# Floor of 1 - G in ``inflated_radii``: a ball buried in its neighbours' field grows at most
# 1 / sqrt(0.3) = 1.8 times instead of without bound.
MIN_FIELD_GAP = 0.3


def projected_radius(scene: Scene, width: int) -> torch.Tensor:
    """Radius ``(B,)`` in pixels of each ball's billboard (world size ``2 r`` at depth ``z``)."""
    return scene.radii / scene.centres[:, 2] / math.tan(math.radians(FOV_DEG)) * width / 2


def draw_inputs(scene: Scene, width: int) -> torch.Tensor:
    """The ``(4, W, W)`` circle image (RGB colour, A centre depth), values in [0, 1].

    Vectorised as a depth test: each pixel shows the nearest ball whose ring covers it,
    which is what drawing far to near gives.
    """
    dtype = scene.centres.dtype
    centre_px = project(scene.centres, width)  # (B, 2) column, row
    radius_px = projected_radius(scene, width)[:, None, None]
    depth = normalised_depth(scene.centres.norm(dim=1))
    coords = torch.arange(width, dtype=dtype) + 0.5
    dist = torch.hypot(
        coords[None, None, :] - centre_px[:, 0, None, None],
        coords[None, :, None] - centre_px[:, 1, None, None],
    )  # (B, W, W)
    ring = (dist > 0.9 * radius_px) & (dist < radius_px)
    nearest, ball = torch.where(ring, depth[:, None, None], math.inf).min(0)
    hit = torch.isfinite(nearest)
    colour = torch.where(hit, scene.colours[ball].permute(2, 0, 1), 0.0)
    return torch.cat([colour, torch.where(hit, nearest, 1.0)[None]]).to(dtype)


def draw_spheres(scene: Scene, width: int) -> GBuffers:
    """Every ball ray-traced as a sphere of its radius ``r`` (the nearest hit per pixel).

    For an isolated ball this is exactly its metaball surface (``r^2 / d^2 = 1`` at
    ``d = r``); colour is the ball's own, normal the sphere's (encoded ``(n + 1) / 2``).
    """
    d = pixel_rays(width, scene.centres.dtype, scene.centres.device).reshape(-1, 3)
    b = d @ scene.centres.T  # (R, B)
    disc = b.square() - (scene.centres.square().sum(1) - scene.radii.square())
    t = torch.where(disc >= 0, b - disc.clamp(min=0).sqrt(), math.inf)
    t = torch.where(t > 0, t, math.inf)
    dist, ball = t.min(1)
    mask = torch.isfinite(dist)
    colour = torch.zeros_like(d)
    normal = torch.zeros_like(d)
    colour[mask] = scene.colours[ball[mask]]
    p = d[mask] * dist[mask, None]
    normal[mask] = ((p - scene.centres[ball[mask]]) / scene.radii[ball[mask], None] + 1) / 2
    depth = torch.where(mask, normalised_depth(dist.nan_to_num(posinf=MAX_DEPTH)), 1.0)
    shape = (width, width)
    return GBuffers(
        colour.T.reshape(3, *shape),
        depth.reshape(1, *shape),
        normal.T.reshape(3, *shape),
        mask.reshape(shape),
    )


def inflated_radii(scene: Scene) -> torch.Tensor:
    """Radius ``(B,)`` of each ball's surface in the field of all the others.

    Near ball ``i`` the other balls add about their field at its centre, ``G_i = sum_{j != i}
    r_j^2 / |P_i - P_j|^2``, so ``r_i^2 / d^2 + G_i = THRESHOLD`` gives a sphere of radius
    ``r_i / sqrt(THRESHOLD - G_i)`` (``THRESHOLD - G_i`` floored at ``MIN_FIELD_GAP``).
    Exact for one ball; a first-order model of the blend otherwise.
    """
    d2 = torch.cdist(scene.centres, scene.centres).square()
    d2.fill_diagonal_(math.inf)
    others = (scene.radii.square()[None, :] / d2).sum(1)
    return scene.radii / (THRESHOLD - others).clamp(min=MIN_FIELD_GAP).sqrt()


def inflated_spheres(scene: Scene, width: int) -> GBuffers:
    """:func:`draw_spheres` with :func:`inflated_radii`: the prior our residual model corrects."""
    return draw_spheres(Scene(scene.centres, inflated_radii(scene), scene.colours), width)
