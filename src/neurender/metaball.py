"""The metaball implicit surface and an exact ray marcher for it (torch).

Field (Blinn 1982; the image-space metaballs thesis, eq. 5.1):
``F(X) = sum_i r_i^2 / |X - P_i|^2``, surface at ``F = THRESHOLD``; an isolated ball is a
sphere of radius ``r``. Rays advance by the largest step that provably cannot cross the
surface: with ``d`` the distance to the nearest centre, any point within ``s`` has
``F <= F (d / (d - s))^2``, so ``s = d (1 - sqrt(F))`` keeps ``F < 1`` (a floor
``min_step`` keeps rays moving near tangencies); the bracketed crossing is then refined by
bisection. Positions are in world units of whatever space the balls live in.
"""

from __future__ import annotations

import dataclasses

import torch

THRESHOLD = 1.0
#: :func:`march`'s step floor (world units) and bisections of the bracketed crossing.
MIN_STEP = 0.02
BISECTIONS = 24


@dataclasses.dataclass
class Scene:
    """Metaballs.

    Attributes:
        centres: ``(B, 3)`` float positions.
        radii: ``(B,)`` size parameters ``r``.
        colours: ``(B, 3)`` linear RGB in [0, 1].
    """

    centres: torch.Tensor
    radii: torch.Tensor
    colours: torch.Tensor

    def __len__(self) -> int:
        return len(self.radii)

    def to(self, dtype: torch.dtype) -> Scene:
        return Scene(self.centres.to(dtype), self.radii.to(dtype), self.colours.to(dtype))


def field(points: torch.Tensor, scene: Scene) -> tuple[torch.Tensor, torch.Tensor]:
    """Field ``F`` ``(R,)`` at points ``(R, 3)`` and the distance to the nearest centre ``(R,)``."""
    d2 = torch.cdist(points, scene.centres).square()
    return (scene.radii.square() / d2).sum(1), d2.min(1).values.sqrt()


def march(
    origins: torch.Tensor,
    dirs: torch.Tensor,
    scene: Scene,
    near: float,
    far: float,
    min_step: float = MIN_STEP,
    bisections: int = BISECTIONS,
) -> torch.Tensor:
    """Distance ``(R,)`` to the first ``F = THRESHOLD`` crossing along each ray in
    ``[near, far]`` (``inf`` if none); rays ``(R, 3)``, directions of unit length."""
    t = torch.full(origins.shape[:1], near, dtype=origins.dtype, device=origins.device)
    prev = t.clone()
    active = torch.ones_like(t, dtype=torch.bool)
    hit = torch.zeros_like(active)
    while active.any():
        idx = active.nonzero().squeeze(1)
        f, dmin = field(origins[idx] + t[idx, None] * dirs[idx], scene)
        crossed = f >= THRESHOLD
        hit[idx[crossed]] = True
        going = idx[~crossed]
        step = (dmin[~crossed] * (1 - f[~crossed].sqrt())).clamp(min=min_step)
        prev[going] = t[going]
        t[going] = t[going] + step
        active[idx[crossed]] = False
        active[going[t[going] > far]] = False
    lo, hi = prev[hit], t[hit]
    o, d = origins[hit], dirs[hit]
    for _ in range(bisections):
        mid = (lo + hi) / 2
        inside = field(o + mid[:, None] * d, scene)[0] >= THRESHOLD
        hi = torch.where(inside, mid, hi)
        lo = torch.where(inside, lo, mid)
    out = torch.full_like(t, float("inf"))
    out[hit] = hi
    return out


def surface_attributes(points: torch.Tensor, scene: Scene) -> tuple[torch.Tensor, torch.Tensor]:
    """Blended colour ``sum c_i f_i / F`` and outward unit normal ``-grad F / |grad F|``
    (each ``(R, 3)``) at points ``(R, 3)`` on (or near) the surface."""
    diff = points[:, None, :] - scene.centres[None]  # (R, B, 3)
    d2 = diff.square().sum(-1)
    f = scene.radii.square() / d2  # (R, B)
    colour = (f @ scene.colours) / f.sum(1, keepdim=True)
    grad = (-2 * scene.radii.square()[None, :, None] * diff / d2[..., None].square()).sum(1)
    return colour, -grad / grad.norm(dim=1, keepdim=True)
