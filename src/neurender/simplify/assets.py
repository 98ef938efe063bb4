"""The two reference assets of the simplification stage (paper 4.1 and 4.5).

* ``head``: the DeepPRT face relief (:func:`neurender.prt.objects.head_mesh`) with skin
  detail (forehead wrinkles, crow's feet, pores) far finer than a 1-5 % decimation can keep;
  an open disk-topology surface facing +z, about 2 x 2.6 units, y up.
* ``metaballs``: a blob creature of coloured metaballs centred at the origin, an implicit
  surface ``F = 1`` of :mod:`neurender.metaballs.raymarch`, rendered by its own ray marcher.

World space is right-handed, y up, units are the assets' own (no physical scale).
"""

from __future__ import annotations

import numpy as np
import torch
import trimesh

from neurender.metaballs.scenes import Scene
from neurender.prt.objects import head_mesh
from neurender.rng import stable_seed

ASSETS = ("head", "metaballs")
CREATURE_RADIUS = 1.7


def skin_detail(x: np.ndarray, y: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Height offsets ``(V,)`` of skin detail at face coordinates x in [-1, 1], y in
    [-1.3, 1.3]: forehead wrinkles (0.16 wavelength, 0.02 deep), crow's feet and random
    bumps (sigma 0.05): a few pixels wide at the default 128 px, finer than the triangles
    of a 1-5 % decimation, coarser than a 128^2 normal map's texels."""
    forehead = np.exp(-0.5 * ((y - 0.8) / 0.22) ** 2) * np.exp(-0.5 * (x / 0.55) ** 2)
    z = 0.02 * forehead * np.sin(2 * np.pi * y / 0.16 + 3.0 * x**2)
    for side in (-1, 1):  # crow's feet fan out from the outer eye corners
        dx, dy = x - 0.62 * side, y - 0.22
        fan = np.exp(-0.5 * (dx**2 + dy**2) / 0.15**2)
        z += 0.015 * fan * np.sin(np.arctan2(dy, dx * side) * 6.0)
    centres = rng.uniform([-1.0, -1.3], [1.0, 1.3], (150, 2))
    heights = rng.uniform(-0.02, 0.02, 150)
    d2 = (x[:, None] - centres[None, :, 0]) ** 2 + (y[:, None] - centres[None, :, 1]) ** 2
    z += (heights * np.exp(-0.5 * d2 / 0.05**2)).sum(1)
    return z


def detailed_head(n_vertices: int, seed: int) -> trimesh.Trimesh:
    """The high-resolution head, ``~2 n_vertices`` triangles, with smooth vertex normals."""
    rng = np.random.default_rng(stable_seed(seed, "simplify", "head"))
    source = head_mesh(n_vertices, rng)
    v = source.vertices.copy()
    v[:, 2] += skin_detail(v[:, 0], v[:, 1], rng)
    # Centre the relief's depth so cameras orbit the middle of the object.
    v[:, 2] -= 0.5 * (v[:, 2].min() + v[:, 2].max())
    return trimesh.Trimesh(v, source.faces, process=False)


def metaball_creature(count: int, seed: int) -> Scene:
    """``count`` coloured balls around the origin (a body with limbs) within a radius of
    about :data:`CREATURE_RADIUS`, float64."""
    g = torch.Generator().manual_seed(stable_seed(seed, "simplify", "metaballs")[0])
    u = torch.rand(count, 7, generator=g, dtype=torch.float64)
    # Balls on a random walk from the origin, so the surface is one connected blob.
    steps = (u[:, :3] * 2 - 1) * 0.55
    centres = torch.cumsum(steps, 0)
    centres = centres - centres.mean(0)
    radii = 0.22 + 0.2 * u[:, 3]
    # F = sum r^2 / d^2 is scale invariant: scale the creature to a fixed size, so one
    # camera distance frames both use cases (a ball's surface reaches ~1.3 r beyond its
    # centre where neighbours add to the field).
    scale = CREATURE_RADIUS / float((centres.norm(dim=1) + 1.3 * radii).max())
    return Scene(centres * scale, radii * scale, u[:, 4:7] * 0.8 + 0.1)
