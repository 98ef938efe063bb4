"""Circle input images of the thesis (section 4.1.1, listing 5.1).

Each ball becomes the outline of a circle at its projected centre: a camera-facing square
billboard of world size ``2 r`` at the ball's centre, with the ring ``0.45 < |uv - 0.5| <
0.5`` of the quad filled, i.e. between 0.9 and 1.0 of the projected radius. RGB = the
ball's colour; A = the normalised depth of the centre. Nearer circles are drawn over
farther ones. Background: RGB 0, A 1 (far).
"""

from __future__ import annotations

import math

import torch

from neurender.metaballs.scenes import FOV_DEG, Scene, normalised_depth, project


def projected_radius(scene: Scene, width: int) -> torch.Tensor:
    """Radius ``(B,)`` in pixels of each ball's billboard (world size ``2 r`` at depth ``z``)."""
    return scene.radii / scene.centres[:, 2] / math.tan(math.radians(FOV_DEG)) * width / 2


def draw_inputs(scene: Scene, width: int) -> torch.Tensor:
    """The ``(4, W, W)`` input image (RGB colour, A depth), values in [0, 1]."""
    image = torch.zeros(4, width, width, dtype=scene.centres.dtype)
    image[3] = 1.0
    centre_px = project(scene.centres, width)
    radius_px = projected_radius(scene, width)
    depth = normalised_depth(scene.centres.norm(dim=1))
    coords = torch.arange(width, dtype=scene.centres.dtype) + 0.5
    for i in torch.argsort(depth, descending=True).tolist():  # far to near: near wins
        cx, cy = centre_px[i].tolist()
        r = float(radius_px[i])
        c0, c1 = max(0, int(cx - r) - 1), min(width, int(cx + r) + 2)
        r0, r1 = max(0, int(cy - r) - 1), min(width, int(cy + r) + 2)
        if c0 >= c1 or r0 >= r1:
            continue
        dist = torch.hypot(coords[c0:c1][None, :] - cx, coords[r0:r1][:, None] - cy)
        ring = (dist > 0.9 * r) & (dist < r)
        for ch in range(3):
            image[ch, r0:r1, c0:c1][ring] = scene.colours[i, ch]
        image[3, r0:r1, c0:c1][ring] = depth[i]
    return image
