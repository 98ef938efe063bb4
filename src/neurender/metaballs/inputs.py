"""What a network sees of a metaball scene: circle images (thesis 4.1.1, listing 5.1) and,
for our residual model, sphere impostors.

Circles: each ball becomes the outline of a circle at its projected centre: a camera-facing
square billboard of world size ``2 r`` at the ball's centre, with the ring ``0.45 < |uv -
0.5| < 0.5`` of the quad filled, i.e. between 0.9 and 1.0 of the projected radius. RGB = the
ball's colour; A = the normalised depth of the centre. Nearer circles are drawn over farther
ones. Background: RGB 0, A 1 (far).

Sphere impostors: every ball ray-traced as a sphere, the nearest hit per pixel, as G-buffers
in the layout of :mod:`neurender.metaballs.gbuffers`. Both cost one test per ball and pixel
(a billboard per ball on a GPU), never a march through the field.
"""

from __future__ import annotations

import math

import torch

from neurender.metaball import THRESHOLD, Scene
from neurender.metaballs.gbuffers import GBuffers, from_hits
from neurender.metaballs.scenes import FOV_DEG, normalised_depth, pixel_rays, project

# Floor of 1 - G in ``inflated_radii``: a ball buried in its neighbours' field grows at most
# 1 / sqrt(0.3) = 1.8 times instead of without bound.
MIN_FIELD_GAP = 0.3


def projected_radius(scene: Scene, width: int) -> torch.Tensor:
    """Radius ``(B,)`` in pixels of each ball's billboard (world size ``2 r`` at depth ``z``)."""
    return scene.radii / scene.centres[:, 2] / math.tan(math.radians(FOV_DEG)) * width / 2


def _footprint_pairs(boxes: torch.Tensor, width: int) -> tuple[torch.Tensor, torch.Tensor]:
    """The (ball, pixel) pairs of each ball's screen rectangle, as a rasteriser visits them.

    Args:
        boxes: ``(B, 4)`` continuous pixel bounds ``x0, y0, x1, y1`` (column, row).

    Returns:
        ``ball (P,)`` and flat pixel index ``row * W + column (P,)`` of every pixel whose
        centre can lie inside (a conservative superset).
    """
    lo = boxes[:, :2].floor().clamp(0, width).long()
    hi = (boxes[:, 2:].ceil() + 1).clamp(0, width).long()
    size = (hi - lo).clamp(min=0)  # (B, 2) columns, rows
    counts = size[:, 0] * size[:, 1]
    ball = torch.repeat_interleave(torch.arange(len(boxes), device=boxes.device), counts)
    start = torch.cumsum(counts, 0) - counts
    local = torch.arange(int(counts.sum()), device=boxes.device) - start[ball]
    cols = size[ball, 0]
    return ball, (lo[ball, 1] + local // cols) * width + lo[ball, 0] + local % cols


def _nearest(ball: torch.Tensor, pixel: torch.Tensor, key: torch.Tensor, width: int):
    """Depth test: per pixel the smallest ``key`` of its pairs (``inf`` where none) and a
    boolean ``(P,)`` marking each pixel's one winning pair: of pairs at equal ``key``, the
    first (pairs come ball by ball, so the lowest ball; writing several winners to one
    pixel would leave which one lands to the thread schedule)."""
    nearest = torch.full((width * width,), math.inf, dtype=key.dtype, device=key.device)
    nearest = nearest.scatter_reduce(0, pixel, key, "amin")
    tied = torch.isfinite(key) & (key == nearest[pixel])
    pair = torch.arange(len(key), device=key.device)
    first = torch.full((width * width,), len(key), dtype=pair.dtype, device=key.device)
    first = first.scatter_reduce(0, pixel[tied], pair[tied], "amin")
    return nearest, tied & (first[pixel] == pair)


def draw_inputs(scene: Scene, width: int) -> torch.Tensor:
    """The ``(4, W, W)`` circle image (RGB colour, A centre depth), values in [0, 1].

    Rasterised like the thesis's billboards (only the pixels of each ball's square), with a
    depth test instead of drawing far to near; the result is the same.
    """
    dtype = scene.centres.dtype
    centre = project(scene.centres, width)  # (B, 2) column, row
    radius = projected_radius(scene, width)
    depth = normalised_depth(scene.centres.norm(dim=1))
    ball, pixel = _footprint_pairs(
        torch.cat([centre - radius[:, None], centre + radius[:, None]], 1), width
    )
    dist = torch.hypot(
        (pixel % width).to(dtype) + 0.5 - centre[ball, 0],
        (pixel // width).to(dtype) + 0.5 - centre[ball, 1],
    )
    ring = (dist > 0.9 * radius[ball]) & (dist < radius[ball])
    nearest, won = _nearest(ball, pixel, torch.where(ring, depth[ball], math.inf), width)
    image = torch.zeros(4, width * width, dtype=dtype, device=scene.centres.device)
    image[:3, pixel[won]] = scene.colours[ball[won]].T
    image[3] = torch.where(torch.isfinite(nearest), nearest, 1.0)
    return image.reshape(4, width, width)


def _sphere_boxes(centres: torch.Tensor, radii: torch.Tensor, width: int) -> torch.Tensor:
    """``(B, 4)`` exact pixel bounds of each sphere's image (spheres in front of the camera).

    The planes ``x = u z`` through the camera tangent to a sphere satisfy
    ``(c_x - u c_z)^2 = r^2 (1 + u^2)``, whose roots bound ``x / z`` on it; likewise ``y / z``.
    """
    cz, r2 = centres[:, 2], radii.square()
    denom = cz.square() - r2
    bounds = []
    for axis in (0, 1):
        c = centres[:, axis]
        half = radii * (c.square() + denom).sqrt()
        bounds.append(((c * cz - half) / denom, (c * cz + half) / denom))
    (u0, u1), (v0, v1) = bounds
    # Corners (u0, v1) and (u1, v0) on the plane z = 1: top-left and bottom-right in pixels.
    ones = torch.ones_like(u0)
    corners = torch.stack([torch.stack([u0, v1, ones], 1), torch.stack([u1, v0, ones], 1)], 1)
    return project(corners.reshape(-1, 3), width).reshape(-1, 4)


def draw_spheres(scene: Scene, width: int) -> GBuffers:
    """Every ball ray-traced as a sphere of its radius ``r`` (the nearest hit per pixel).

    For an isolated ball this is exactly its metaball surface (``r^2 / d^2 = 1`` at
    ``d = r``); colour is the ball's own, normal the sphere's (encoded ``(n + 1) / 2``).
    Rasterised per ball over its screen rectangle (a sphere impostor).
    """
    dtype = scene.centres.dtype
    ball, pixel = _footprint_pairs(_sphere_boxes(scene.centres, scene.radii, width), width)
    rays = pixel_rays(width, dtype, scene.centres.device).reshape(-1, 3)
    # |c|^2 - r^2 and the ray-centre projections b per ball: the per-pair work is gathers.
    b = (rays @ scene.centres.T).reshape(-1)[pixel * len(scene) + ball]
    disc = b.square() - (scene.centres.square().sum(1) - scene.radii.square())[ball]
    t = torch.where(disc >= 0, b - disc.clamp(min=0).sqrt(), math.inf)
    dist, won = _nearest(ball, pixel, torch.where(t > 0, t, math.inf), width)
    hit, ball = pixel[won], ball[won]
    colour = torch.zeros(3, width * width, dtype=dtype, device=scene.centres.device)
    normal = torch.zeros_like(colour)
    colour[:, hit] = scene.colours[ball].T
    points = rays[hit] * dist[hit, None]
    normal[:, hit] = (((points - scene.centres[ball]) / scene.radii[ball, None] + 1) / 2).T
    return from_hits(dist, colour, normal, width)


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
