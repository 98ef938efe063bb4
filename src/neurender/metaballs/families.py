"""Scene families that keep a constant density of balls whatever their number, framed by
the camera, with no walls: the balls shrink as their number grows, and statistics of the
frames they make.

View space, camera and depths of :mod:`neurender.metaballs.scenes`. Every family fills a
region around the point ``(0, 0, CENTRE_DEPTH)`` on the view axis whose balls' reach
(``support x r``, :attr:`neurender.metaball.Scene.reach`; ``r`` for the inverse square,
whose reach is unbounded) stays inside the sphere of radius :func:`bound_radius` around
it: inside the view cone (half-angle ``FOV_DEG``, the cone inscribed in the square image)
by ``margin``, and with its nearest point deeper than ``MIN_DEPTH + NEAR_GAP`` (so the near
plane never cuts the surface: no pixel starts inside it).

Packing fraction: the balls' volume ``sum 4/3 pi r_i^3`` over the volume of the region
their centres fill. Radii are ``r_i = rbar (1 + spread v_i)``, ``v_i`` uniform in [-1, 1],
``rbar`` set so that the packing is exactly the one asked for; every random number comes
from the caller's generator (float64).
"""

from __future__ import annotations

import math

import torch

from neurender.metaball import Kernel, Scene
from neurender.metaballs import inputs
from neurender.metaballs.gbuffers import GBuffers
from neurender.metaballs.scenes import FOV_DEG, MAX_DEPTH, MIN_DEPTH

#: Depth (world units) of the families' centre on the view axis: mid-range.
CENTRE_DEPTH = (MIN_DEPTH + MAX_DEPTH) / 2
#: How much deeper than ``MIN_DEPTH`` the nearest reach of a ball stays (world units).
NEAR_GAP = 1.0
#: Default gap (world units) between the balls' reach and the view cone.
MARGIN = 0.5
#: The families' default kernel: Wyvill's, reaching twice a ball's radius.
WYVILL = Kernel("wyvill", 2.0)


def bound_radius(margin: float = MARGIN) -> float:
    """Radius (world units) of the sphere around ``(0, 0, CENTRE_DEPTH)`` that holds every
    ball's reach: the largest inside the view cone, less ``margin``, and no nearer the
    camera than ``MIN_DEPTH + NEAR_GAP`` (module docstring)."""
    cone = CENTRE_DEPTH * math.sin(math.radians(FOV_DEG))
    return min(cone - margin, CENTRE_DEPTH - MIN_DEPTH - NEAR_GAP)


def _check(count: int, packing: float, radius_spread: float, margin: float) -> None:
    if count < 1:
        raise ValueError(f"a scene family needs at least one ball, not {count}")
    if not 0 < packing < 1:
        raise ValueError(f"packing fraction {packing} must be in (0, 1)")
    if not 0 <= radius_spread < 1:
        raise ValueError(f"radius_spread {radius_spread} must be in [0, 1)")
    if not 0 <= margin < bound_radius(0):
        raise ValueError(f"margin {margin} must be in [0, {bound_radius(0)}) world units")


def _reach_per_radius(kernel: Kernel) -> float:
    """A ball's reach in units of its ``r`` (``support``; 1 for the inverse square)."""
    return kernel.support if kernel.finite else 1.0


def _radius_weights(count: int, spread: float, generator: torch.Generator) -> torch.Tensor:
    """``(count,)`` float64 ``1 + spread v``, ``v`` uniform in [-1, 1]."""
    v = torch.rand(count, generator=generator, dtype=torch.float64) * 2 - 1
    return 1 + spread * v


def cluster(
    count: int,
    generator: torch.Generator,
    packing: float = 0.15,
    kernel: Kernel = WYVILL,
    radius_spread: float = 0.3,
    margin: float = MARGIN,
) -> Scene:
    """``count`` balls at a constant number density in a ball-shaped cluster on the view
    axis (module docstring).

    Centres are uniform in the sphere of radius ``R`` around ``(0, 0, CENTRE_DEPTH)``, ``R
    + reach of the largest possible ball (rbar (1 + spread) s) = bound_radius(margin)``;
    ``sum r_i^3 = packing R^3``, so ``rbar`` shrinks about as ``count^(-1/3)`` (``R``
    grows towards the bound as the balls shrink). Colours uniform in [0, 1].

    Returns:
        float64 :class:`~neurender.metaball.Scene` of ``kernel``.
    """
    _check(count, packing, radius_spread, margin)
    direction = torch.randn(count, 3, generator=generator, dtype=torch.float64)
    direction = direction / direction.norm(dim=1, keepdim=True)
    radial = torch.rand(count, generator=generator, dtype=torch.float64).pow(1 / 3)
    weights = _radius_weights(count, radius_spread, generator)
    colours = torch.rand(count, 3, generator=generator, dtype=torch.float64)
    # rbar (sum w^3)^(1/3) = packing^(1/3) R with R = bound - s (1 + spread) rbar
    bound, grow = bound_radius(margin), _reach_per_radius(kernel) * (1 + radius_spread)
    cube_root = packing ** (1 / 3)
    rbar = cube_root * bound / (float(weights.pow(3).sum()) ** (1 / 3) + cube_root * grow)
    extent = bound - grow * rbar
    centre = torch.tensor([0.0, 0.0, CENTRE_DEPTH], dtype=torch.float64)
    return Scene(centre + extent * radial[:, None] * direction, rbar * weights, colours, kernel)


def sheet(
    count: int,
    generator: torch.Generator,
    packing: float = 0.15,
    kernel: Kernel = WYVILL,
    radius_spread: float = 0.3,
    layers: float = 2.0,
    tilt_deg: float = 60.0,
    amplitude: float = 0.5,
    waves: int = 4,
    margin: float = MARGIN,
) -> Scene:
    """``count`` balls in a thin wavy sheet, like a fluid's free surface seen at an angle.

    In the sheet's frame ``(u, v, w)`` the centres are uniform in the disc ``u^2 + v^2 <
    D^2`` and in ``w`` within ``h / 2`` of the height field ``H(u, v) = amplitude x`` the
    mean of ``waves`` random plane waves (1 to 3 cycles over ``D``); the thickness ``h = 2
    layers rbar`` is a few balls, so ``rbar`` shrinks about as ``count^(-1/2)`` and a ray
    crosses about as many balls whatever their number. Packing: ``sum 4/3 pi r_i^3 = packing
    pi D^2 h``. The sheet faces the camera tilted by ``tilt_deg`` about the x axis (its far
    side deeper) around ``(0, 0, CENTRE_DEPTH)``; ``D`` is the largest with ``sqrt(D^2 +
    (amplitude + h / 2)^2) +`` the largest possible reach ``<= bound_radius(margin)``.

    Returns:
        float64 :class:`~neurender.metaball.Scene` of ``kernel``.
    """
    _check(count, packing, radius_spread, margin)
    if layers <= 0 or amplitude < 0 or waves < 1:
        raise ValueError(
            f"sheet: layers {layers} must be positive, amplitude {amplitude} non-negative "
            f"and waves {waves} at least 1"
        )
    bound = bound_radius(margin)
    if amplitude >= bound:
        raise ValueError(f"sheet amplitude {amplitude} must be below {bound} world units")
    angle = torch.rand(count, generator=generator, dtype=torch.float64) * 2 * math.pi
    spot = torch.rand(count, generator=generator, dtype=torch.float64).sqrt()
    depth = torch.rand(count, generator=generator, dtype=torch.float64) - 0.5
    weights = _radius_weights(count, radius_spread, generator)
    colours = torch.rand(count, 3, generator=generator, dtype=torch.float64)
    wave = torch.rand(waves, 3, generator=generator, dtype=torch.float64)
    # rbar = D sqrt(1.5 packing layers / sum w^3) = c D; the largest D whose sheet and
    # reach fit the bound, by bisection (the extent grows with D).
    c = math.sqrt(1.5 * packing * layers / float(weights.pow(3).sum()))
    grow = _reach_per_radius(kernel) * (1 + radius_spread)

    def extent(d: float) -> float:
        return math.hypot(d, amplitude + layers * c * d) + grow * c * d

    lo, hi = 0.0, bound
    for _ in range(60):
        lo, hi = ((lo + hi) / 2, hi) if extent((lo + hi) / 2) <= bound else (lo, (lo + hi) / 2)
    disc = lo
    rbar = c * disc
    u, v = disc * spot * angle.cos(), disc * spot * angle.sin()
    heading = wave[:, 0] * 2 * math.pi
    cycles = (1 + 2 * wave[:, 1]) * 2 * math.pi / disc
    phase = u[:, None] * heading.cos() + v[:, None] * heading.sin()
    height = amplitude * torch.sin(cycles * phase + wave[:, 2] * 2 * math.pi).mean(1)
    w = height + 2 * layers * rbar * depth
    tilt = math.radians(tilt_deg)
    centres = torch.stack(
        [
            u,
            v * math.cos(tilt) + w * math.sin(tilt),
            CENTRE_DEPTH + v * math.sin(tilt) - w * math.cos(tilt),
        ],
        1,
    )
    return Scene(centres, rbar * weights, colours, kernel)


def frame_stats(scene: Scene, buffers: GBuffers) -> dict[str, float]:
    """What a frame of a scene asks of a renderer, from its exact G-buffers (e.g.
    :func:`neurender.metaballs.raymarch.render_gbuffers`).

    Returns:
        ``covered``: the share of pixels the surface covers; ``near_plane``: the share of
        pixels whose surface is at ``MIN_DEPTH`` (the ray starts inside it; normalised
        depth 0); ``depth_complexity``: balls per covered pixel, the mean over covered
        pixels of how many balls' spheres of reach the pixel's ray passes through, counted
        exactly per pixel by the impostor rasteriser
        (:func:`neurender.metaballs.inputs.sphere_counts`: one test per ball and pixel of
        its reach's screen rectangle); every ball for the inverse square; NaN when nothing
        is covered.
    """
    mask = buffers.mask
    width = mask.shape[-1]
    covered = mask.reshape(-1)
    near = covered & (buffers.depth.reshape(-1) <= 0)
    if not covered.any():
        complexity = math.nan
    elif scene.kernel.finite:
        reach = Scene(scene.centres, scene.reach, scene.colours)
        counts = inputs.sphere_counts(reach, width)
        complexity = float(counts[covered].double().mean())
    else:
        complexity = float(len(scene))
    return {
        "covered": float(covered.double().mean()),
        "near_plane": float(near.double().mean()),
        "depth_complexity": complexity,
    }
