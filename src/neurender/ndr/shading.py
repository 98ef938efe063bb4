"""Coarse shading inputs ``S_D`` and ``S_S`` (paper 3.1), in torch.

Each pixel is treated as a lone point: no occlusion, no neighbours. ``S_D`` estimates the
Lambertian shading ``integral L(w) max(n.w, 0) / pi dw`` with cosine-weighted samples;
``S_S`` estimates the GGX shading with Fresnel = 1,
``integral L(l) D(h) G(v, l) / (4 (n.v)) dl``, by sampling half vectors from
``D(h) (n.h)`` (Walter et al. 2007; Karis 2013), weight ``G (v.h) / ((n.h)(n.v))``, with the
separable Smith ``G`` of GGX that Mitsuba's ``roughconductor`` uses. ``L`` is read (nearest
texel) from a small lat-long copy of the map (paper: 32 x 16). Samples are a jittered
``sqrt(n) x sqrt(n)`` grid, randomly rotated per pixel (Cranley-Patterson).

Directions are world = view space (see :mod:`neurender.ndr.render`); ``alpha`` is the GGX
width (roughness squared).
"""

from __future__ import annotations

import math

import torch


def _frame(n: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Two unit tangents ``(P, 3)`` completing ``n`` to an orthonormal frame (Duff et al. 2017)."""
    sign = torch.where(n[:, 2] >= 0, 1.0, -1.0).to(n.dtype)
    a = -1.0 / (sign + n[:, 2])
    b = n[:, 0] * n[:, 1] * a
    t = torch.stack([1 + sign * n[:, 0] ** 2 * a, sign * b, -sign * n[:, 0]], -1)
    s = torch.stack([b, sign + n[:, 1] ** 2 * a, -n[:, 1]], -1)
    return t, s


def _unit_square(pixels: int, samples: int, generator: torch.Generator) -> torch.Tensor:
    """``(P, S, 2)`` jittered-grid samples in [0, 1)^2, rotated per pixel."""
    side = math.isqrt(samples)
    if side * side != samples:
        raise ValueError(f"coarse shading samples={samples}: expected a square number (e.g. 64)")
    i = torch.arange(side, dtype=torch.float64)
    grid = torch.stack(torch.meshgrid(i, i, indexing="ij"), -1).reshape(-1, 2)
    jitter = torch.rand(samples, 2, generator=generator, dtype=torch.float64)
    base = (grid + jitter) / side
    shift = torch.rand(pixels, 1, 2, generator=generator, dtype=torch.float64)
    return torch.remainder(base[None] + shift, 1.0)


def lookup(environment: torch.Tensor, dirs: torch.Tensor) -> torch.Tensor:
    """Radiance ``(..., 3)`` of a lat-long map ``(H, 2H, 3)`` at unit ``dirs`` ``(..., 3)``,
    nearest texel (convention of :mod:`neurender.sh`)."""
    h, w = environment.shape[:2]
    theta = torch.arccos(dirs[..., 1].clamp(-1, 1))
    phi = torch.remainder(torch.atan2(dirs[..., 0], -dirs[..., 2]), 2 * math.pi)
    row = (theta / math.pi * h).long().clamp(0, h - 1)
    col = (phi / (2 * math.pi) * w).long().clamp(0, w - 1)
    return environment[row, col]


def smith_g1(cos_theta: torch.Tensor, alpha: torch.Tensor) -> torch.Tensor:
    """Smith masking of GGX for a direction at ``cos_theta`` to the normal."""
    c2 = cos_theta.clamp(1e-7, 1) ** 2
    tan2 = (1 - c2) / c2
    return 2 / (1 + torch.sqrt(1 + alpha**2 * tan2))


def coarse_shading(
    normals: torch.Tensor,
    view_dirs: torch.Tensor,
    alpha: torch.Tensor,
    environment: torch.Tensor,
    samples: int,
    generator: torch.Generator,
) -> tuple[torch.Tensor, torch.Tensor]:
    """``S_D`` and ``S_S`` ``(P, 3)`` for ``P`` surface points.

    Args:
        normals, view_dirs: ``(P, 3)`` unit vectors (view_dir points to the eye).
        alpha: ``(P,)`` GGX width.
        environment: ``(h, 2h, 3)`` linear radiance (e.g. 16 x 32).
        samples: per pixel and lobe, a square number.
        generator: seeds the sample pattern (deterministic given its seed).
    """
    n = normals.double()
    v = view_dirs.double()
    env = environment.double()
    t, s = _frame(n)
    u = _unit_square(len(n), samples, generator)

    # Lambert: cosine-weighted directions; the estimator is the mean radiance.
    r = torch.sqrt(u[..., 0:1])
    phi = 2 * math.pi * u[..., 1:2]
    z = torch.sqrt((1 - u[..., 0:1]).clamp(min=0))
    local = torch.cat([r * torch.cos(phi), r * torch.sin(phi), z], -1)
    world = (
        local[..., 0:1] * t[:, None] + local[..., 1:2] * s[:, None] + local[..., 2:3] * n[:, None]
    )
    s_d = lookup(env, world).mean(1)

    # GGX: half vectors from D(h) (n.h), reflected about h.
    a = alpha.double()[:, None]
    u = _unit_square(len(n), samples, generator)
    tan2 = a**2 * u[..., 0] / (1 - u[..., 0]).clamp(min=1e-12)
    cos_h = 1 / torch.sqrt(1 + tan2)
    sin_h = torch.sqrt((1 - cos_h**2).clamp(min=0))
    phi = 2 * math.pi * u[..., 1]
    h = (
        (sin_h * torch.cos(phi))[..., None] * t[:, None]
        + (sin_h * torch.sin(phi))[..., None] * s[:, None]
        + cos_h[..., None] * n[:, None]
    )
    v_dot_h = (v[:, None] * h).sum(-1)
    light = 2 * v_dot_h[..., None] * h - v[:, None]
    n_dot_l = (n[:, None] * light).sum(-1)
    n_dot_v = (n * v).sum(-1, keepdim=True)
    valid = (n_dot_l > 0) & (v_dot_h > 0) & (n_dot_v > 0)
    g = smith_g1(n_dot_l, a) * smith_g1(n_dot_v.expand_as(n_dot_l), a)
    weight = torch.where(valid, g * v_dot_h / (cos_h * n_dot_v.clamp(min=1e-7)), 0.0)
    s_s = (lookup(env, light) * weight[..., None]).mean(1)
    return s_d.to(normals.dtype), s_s.to(normals.dtype)
