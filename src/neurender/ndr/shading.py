"""Coarse shading inputs ``S_D`` and ``S_S`` (paper 3.1), in torch.

Each pixel is treated as a lone point: no occlusion, no neighbours. ``S_D`` estimates the
Lambertian shading ``integral L(w) max(n.w, 0) / pi dw`` with cosine-weighted samples;
``S_S`` estimates the GGX shading with Fresnel = 1,
``integral L(l) D(h) G(v, l) / (4 (n.v)) dl``, by sampling half vectors from
``D(h) (n.h)`` (Walter et al. 2007; Karis 2013), weight ``G (v.h) / ((n.h)(n.v))``, with the
separable Smith ``G`` of GGX that Mitsuba's ``roughconductor`` uses. ``L`` is read (nearest
texel) from a small lat-long copy of the map (paper: 32 x 16). Samples are a jittered
``sqrt(n) x sqrt(n)`` grid, randomly rotated per pixel (Cranley-Patterson).

Bright texels (our change; the paper importance-samples the BRDFs only): on real outdoor
maps the sun holds more than half of the map's power in one texel of the 32 x 16 map, which
64 BRDF samples hit or miss at random, so the shading speckles. The texels brighter than
:data:`BRIGHT_RATIO` x the map's mean radiance (at most :data:`MAX_BRIGHT`, the most
powerful) are therefore also sampled explicitly, ``samples`` more per pixel and lobe: a
texel by its power, a direction uniformly in its solid angle. Both strategies are combined
by multiple importance sampling (Veach and Guibas 1995, balance heuristic) on the bright
texels; the rest of the map is BRDF-sampled as before. The estimate stays unbiased, and a
map without bright texels (e.g. the white furnace's constant map) is shaded exactly as the
plain estimator does.

Directions are world = view space (see :mod:`neurender.ndr.render`); ``alpha`` is the GGX
width (roughness squared).
"""

from __future__ import annotations

import dataclasses
import math

import torch

#: A texel is sampled explicitly when its radiance (mean over RGB) exceeds this multiple of
#: the map's mean radiance; at most :data:`MAX_BRIGHT` texels, the most powerful, are.
BRIGHT_RATIO = 8.0
MAX_BRIGHT = 16


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
    # Squares as products: an ONNX Pow costs several Muls (neurender.ndr.prefiltered).
    c = cos_theta.clamp(1e-7, 1.0)  # float bounds: see neurender.ndr.prefiltered
    c2 = c * c
    tan2 = (1 - c2) / c2
    return 2 / (1 + torch.sqrt(1 + alpha * alpha * tan2))


def ggx_d(cos_h: torch.Tensor, alpha: torch.Tensor) -> torch.Tensor:
    """GGX normal distribution ``D(h)`` at ``cos_h = n.h`` (0 below the surface)."""
    c = cos_h.clamp(min=0)
    a2 = alpha * alpha
    denominator = c * c * (a2 - 1) + 1
    d = a2 / (math.pi * denominator * denominator)
    return torch.where(cos_h > 0, d, 0.0)


@dataclasses.dataclass
class BrightTexels:
    """The texels of a lat-long map ``(h, 2h, 3)`` sampled explicitly.

    ``rows``, ``cols`` ``(K,)`` long; ``probability`` ``(K,)`` of choosing each (its share
    of the bright texels' power); ``pdf`` ``(h, 2h)`` the density in solid angle of the
    light-sampling strategy (``probability / texel solid angle`` on a bright texel, 0
    elsewhere).
    """

    rows: torch.Tensor
    cols: torch.Tensor
    probability: torch.Tensor
    pdf: torch.Tensor

    def sample(self, u: torch.Tensor, height: int) -> tuple[torch.Tensor, torch.Tensor]:
        """Directions ``(..., 3)`` from ``u`` ``(..., 2)`` in [0, 1)^2 and the index of the
        chosen texel ``(...)``: ``u[..., 0]`` picks a texel by its probability and, rescaled,
        ``cos theta`` within it; ``u[..., 1]`` the azimuth within it."""
        cdf = torch.cumsum(self.probability, 0)
        k = torch.searchsorted(cdf, u[..., 0].contiguous(), right=True).clamp(max=len(cdf) - 1)
        start = cdf[k] - self.probability[k]
        v = ((u[..., 0] - start) / self.probability[k]).clamp(0, 1)
        row, col = self.rows[k].double(), self.cols[k].double()
        cos0, cos1 = torch.cos(math.pi * row / height), torch.cos(math.pi * (row + 1) / height)
        cos_t = cos0 - v * (cos0 - cos1)
        sin_t = torch.sqrt((1 - cos_t**2).clamp(min=0))
        phi = (col + u[..., 1]) * math.pi / height  # the map is 2 h wide: 2 pi / (2 h)
        dirs = torch.stack([sin_t * torch.sin(phi), cos_t, -sin_t * torch.cos(phi)], -1)
        return dirs, k


def bright_texels(
    environment: torch.Tensor, ratio: float = BRIGHT_RATIO, limit: int = MAX_BRIGHT
) -> BrightTexels | None:
    """The texels of ``environment`` ``(h, 2h, 3)`` brighter than ``ratio`` x its mean
    radiance (weighted by solid angle), at most ``limit`` (the most powerful); ``None``
    when there are none (or ``limit`` is 0)."""
    h, w = environment.shape[:2]
    edges = torch.cos(math.pi * torch.arange(h + 1, dtype=torch.float64) / h)
    solid = ((edges[:-1] - edges[1:]) * (2 * math.pi / w))[:, None].expand(h, w)
    radiance = environment.double().mean(-1)
    mean = (radiance * solid).sum() / (4 * math.pi)
    power = (radiance * solid).flatten()
    candidates = (radiance.flatten() > ratio * mean) & (power > 0)
    count = min(int(candidates.sum()), limit)
    if count == 0:
        return None
    chosen = torch.argsort(torch.where(candidates, power, -1.0), descending=True)[:count]
    probability = power[chosen] / power[chosen].sum()
    pdf = torch.zeros(h * w, dtype=torch.float64)
    pdf[chosen] = probability / solid.flatten()[chosen]
    return BrightTexels(chosen // w, chosen % w, probability, pdf.reshape(h, w))


def coarse_shading(
    normals: torch.Tensor,
    view_dirs: torch.Tensor,
    alpha: torch.Tensor,
    environment: torch.Tensor,
    samples: int,
    generator: torch.Generator,
    max_bright: int = MAX_BRIGHT,
) -> tuple[torch.Tensor, torch.Tensor]:
    """``S_D`` and ``S_S`` ``(P, 3)`` for ``P`` surface points.

    Args:
        normals, view_dirs: ``(P, 3)`` unit vectors (view_dir points to the eye).
        alpha: ``(P,)`` GGX width.
        environment: ``(h, 2h, 3)`` linear radiance (e.g. 16 x 32).
        samples: per pixel and lobe, a square number (as many again per lobe for the
            bright texels, when the map has any).
        generator: seeds the sample pattern (deterministic given its seed).
        max_bright: at most this many texels sampled explicitly (see the module
            docstring); 0 is the paper's plain BRDF sampling.
    """
    n = normals.double()
    v = view_dirs.double()
    env = environment.double()
    bright = bright_texels(env, limit=max_bright)
    light_pdf = bright.pdf if bright is not None else None
    frame = (*_frame(n), n)
    # The order of the draws from ``generator`` is the sample pattern: diffuse, specular,
    # then the bright texels' diffuse and specular.
    s_d = _brdf_sampled_diffuse(frame, env, light_pdf, samples, generator)
    a = alpha.double()[:, None]
    s_s = _brdf_sampled_specular(frame, v, a, env, light_pdf, samples, generator)
    if bright is not None:
        s_d = s_d + _bright_diffuse(n, env, bright, samples, generator)
        s_s = s_s + _bright_specular(n, v, a, env, bright, samples, generator)
    return s_d.to(normals.dtype), s_s.to(normals.dtype)


def _mis(p_brdf: torch.Tensor, p_light: torch.Tensor) -> torch.Tensor:
    """Balance-heuristic weight of a strategy with density ``p_brdf`` against the other
    (equal sample counts); 1 where the other cannot make the direction."""
    total = p_brdf + p_light
    return torch.where(p_light > 0, p_brdf / total.clamp(min=1e-300), 1.0)


def _brdf_sampled_diffuse(
    frame: tuple[torch.Tensor, ...],
    env: torch.Tensor,
    light_pdf: torch.Tensor | None,
    samples: int,
    generator: torch.Generator,
) -> torch.Tensor:
    """Lambert's ``S_D`` ``(P, 3)`` from cosine-weighted directions (the estimator is the
    mean radiance) about the ``(t, s, n)`` frame ``(P, 3)`` each, MIS-weighted against the
    bright texels' light sampling where ``light_pdf`` (their density map) is given."""
    t, s, n = frame
    u = _unit_square(len(n), samples, generator)
    r = torch.sqrt(u[..., 0:1])
    phi = 2 * math.pi * u[..., 1:2]
    z = torch.sqrt((1 - u[..., 0:1]).clamp(min=0))
    local = torch.cat([r * torch.cos(phi), r * torch.sin(phi), z], -1)
    world = (
        local[..., 0:1] * t[:, None] + local[..., 1:2] * s[:, None] + local[..., 2:3] * n[:, None]
    )
    radiance = lookup(env, world)
    if light_pdf is not None:
        radiance = (
            radiance
            * _mis(z[..., 0] / math.pi, lookup(light_pdf[..., None], world)[..., 0])[..., None]
        )
    return radiance.mean(1)


def _brdf_sampled_specular(
    frame: tuple[torch.Tensor, ...],
    v: torch.Tensor,
    a: torch.Tensor,
    env: torch.Tensor,
    light_pdf: torch.Tensor | None,
    samples: int,
    generator: torch.Generator,
) -> torch.Tensor:
    """GGX's ``S_S`` ``(P, 3)`` for view directions ``v`` ``(P, 3)`` and widths ``a``
    ``(P, 1)``: half vectors drawn from ``D(h) (n.h)`` about the ``(t, s, n)`` frame,
    reflected about ``h``; MIS-weighted as :func:`_brdf_sampled_diffuse`."""
    t, s, n = frame
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
    if light_pdf is not None:
        p_brdf = ggx_d(cos_h, a) * cos_h / (4 * v_dot_h.clamp(min=1e-12))
        weight = weight * _mis(p_brdf, lookup(light_pdf[..., None], light)[..., 0])
    return (lookup(env, light) * weight[..., None]).mean(1)


def _light_samples(
    bright: BrightTexels, env: torch.Tensor, pixels: int, samples: int, generator
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Directions ``(P, S, 3)`` sampled on the bright texels, their radiance ``(P, S, 3)``
    and light-sampling density ``(P, S)`` (the chosen texel's, so rounding at a texel's
    edge cannot pair one texel's radiance with another's density)."""
    u = _unit_square(pixels, samples, generator)
    dirs, k = bright.sample(u, env.shape[0])
    rows, cols = bright.rows[k], bright.cols[k]
    return dirs, env[rows, cols], bright.pdf[rows, cols]


def _bright_diffuse(n, env, bright: BrightTexels, samples: int, generator) -> torch.Tensor:
    """The light-sampling half of ``S_D``'s MIS estimate ``(P, 3)``."""
    dirs, radiance, p_light = _light_samples(bright, env, len(n), samples, generator)
    cosine = (n[:, None] * dirs).sum(-1).clamp(min=0) / math.pi  # BRDF x cos = its pdf
    weight = torch.where(cosine > 0, cosine / (cosine + p_light), 0.0)
    return (radiance * weight[..., None]).mean(1)


def _bright_specular(n, v, a, env, bright: BrightTexels, samples: int, generator) -> torch.Tensor:
    """The light-sampling half of ``S_S``'s MIS estimate ``(P, 3)``."""
    light, radiance, p_light = _light_samples(bright, env, len(n), samples, generator)
    h = light + v[:, None]
    h = h / h.norm(dim=-1, keepdim=True).clamp(min=1e-12)
    n_dot_l = (n[:, None] * light).sum(-1)
    n_dot_v = (n * v).sum(-1, keepdim=True).expand_as(n_dot_l)
    cos_h = (n[:, None] * h).sum(-1)
    v_dot_h = (v[:, None] * h).sum(-1)
    d = ggx_d(cos_h, a)
    valid = (n_dot_l > 0) & (n_dot_v > 0) & (v_dot_h > 0) & (cos_h > 0)
    f_cos = d * smith_g1(n_dot_l, a) * smith_g1(n_dot_v, a) / (4 * n_dot_v.clamp(min=1e-7))
    p_brdf = d * cos_h / (4 * v_dot_h.clamp(min=1e-12))
    weight = torch.where(valid, f_cos / (p_brdf + p_light), 0.0)
    return (radiance * weight[..., None]).mean(1)
