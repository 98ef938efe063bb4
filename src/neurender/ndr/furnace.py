"""White-furnace checks of the NDR ground truth and coarse shading.

A convex white object under a constant unit environment reflects exactly 1 diffusely
(``I_D = 1`` everywhere: no occlusion on a convex shape, the cosine integral over pi is 1),
and its specular map is the GGX directional albedo, which Mitsuba's ``roughconductor`` and
our coarse-shading estimators compute independently (the importance-sampled one and the
prefiltered one of :mod:`neurender.ndr.prefiltered`, whose ``S_D`` comes from the map's SH
and ``S_S`` from its albedo table). Each check is a
:class:`neurender.tables.Target` (subject ``Mitsuba I_D``, ``coarse S_D`` ...).

The sun check: the same sphere under a sky with a half-degree sun that holds most of the
map's power (:func:`sun_map`), where a convex object's ``I_D`` is the unoccluded shading
the coarse ``S_D`` estimates. Its error against Mitsuba is stated for the coarse estimator
(bright texels sampled explicitly, :mod:`neurender.ndr.shading`) beside the paper's plain
BRDF sampling, whose shading speckles under such maps, and beside the prefiltered shading's
SH irradiance, which blurs the sun over the 5 bands' resolution.
"""

from __future__ import annotations

import numpy as np
import torch
import trimesh

from neurender import sh
from neurender.ndr import environments, prefiltered, render, shading
from neurender.ndr.objects import ProceduralObject
from neurender.ndr.shading import coarse_shading
from neurender.rng import torch_generator
from neurender.tables import Target

#: The furnace's camera (the NDR default) and its unit environment map.
FURNACE_DISTANCE, FURNACE_FOV = 3.9, 30.0
FURNACE_ENVIRONMENT = (32, 64)
#: Uniform roughness of the sphere: a mid-width GGX lobe.
FURNACE_ROUGHNESS = 0.5
#: Tolerances: Mitsuba's mean ``I_D`` (its Monte Carlo error over the sphere), the coarse
#: ``S_D`` (exact up to float error: a constant map) and the relative difference of the two
#: GGX albedo estimates.
I_D_TOLERANCE, S_D_TOLERANCE, GGX_TOLERANCE = 0.01, 1e-6, 0.02
#: The prefiltered ``S_D``'s tolerance: the SH of the 32 x 64 unit map by midpoint
#: quadrature, whose solid angles sum to 4 pi only up to 1e-3.
PREFILTERED_S_D_TOLERANCE = 1e-3
#: The sun check's map: rows, the sun's direction (upper right, towards the camera) and its
#: radiance as a multiple of the sky's; and the tolerated mean relative error of ``S_D``
#: (what is left is the coarse map's blur of the sun over one 11-degree texel).
SUN_MAP_HEIGHT, SUN_DIRECTION, SUN_RADIANCE = 64, (0.45, 0.6, 0.66), 2e5
SUN_TOLERANCE = 0.25


def white_sphere(roughness: float) -> ProceduralObject:
    """A unit sphere (icosphere, 20,480 faces) with uniform ``roughness`` and white albedos."""
    mesh = trimesh.creation.icosphere(subdivisions=5)
    v = np.asarray(mesh.vertices, np.float32)
    ones = np.ones_like(v)
    return ProceduralObject(
        v, np.asarray(mesh.faces, np.int32), ones, ones, np.full(len(v), roughness, np.float32), 1
    )


def sun_map(height: int = SUN_MAP_HEIGHT) -> np.ndarray:
    """A sky (0.5 above the horizon, 0.1 below) with a half-degree sun of
    :data:`SUN_RADIANCE` x the sky (:func:`neurender.ndr.environments.add_small_sun`):
    about two thirds of the map's power in one texel, as on real outdoor maps."""
    dirs = sh.latlong_directions(height, 2 * height)[0]
    sky = np.where(dirs[..., 1:2] > 0, 0.5, 0.1) * np.ones(3)
    direction = np.asarray(SUN_DIRECTION) / np.linalg.norm(SUN_DIRECTION)
    return environments.add_small_sun(sky.astype(np.float32), direction, 0.5 * SUN_RADIANCE)


def _within(
    subject: str, what: str, measured: float, expected: float, tol: float, why: str = ""
) -> Target:
    check = f"{what} within {why}{tol:.3g} of {expected:g}"
    return Target(subject, check, measured, abs(measured - expected) <= tol)


def _coarse(g: dict, inside: np.ndarray, env: np.ndarray, samples: int, seed: int, **kw):
    n = torch.from_numpy(g["normal"][inside])
    return coarse_shading(
        n,
        torch.from_numpy(g["view_dir"][inside]),
        torch.full((len(n),), FURNACE_ROUGHNESS**2),
        torch.from_numpy(env),
        samples,
        torch_generator(seed, "furnace"),
        **kw,
    )


def sun_check(mi, width: int, spp: int, samples: int, coarse_height: int, seed: int) -> Target:
    """The sun check (module docstring): mean ``|S_D - I_D|`` over mean ``I_D`` on the
    sphere's interior pixels, the map downsampled to ``coarse_height`` rows."""
    obj = white_sphere(FURNACE_ROUGHNESS)
    view = render.camera(FURNACE_DISTANCE, FURNACE_FOV)
    env = sun_map()
    maps = render.shading_maps(mi, obj, env, view, width, spp, seed, specular=False)
    g = render.g_buffers(obj, view, width)
    inside = (g["mask"] > 0) & (maps["coverage"] > 0.999)
    small = environments.resize_latlong(env, coarse_height)
    i_d = maps["I_D"][inside]
    errors = {}
    for name, bright in (("bright texels", shading.MAX_BRIGHT), ("plain", 0)):
        s_d, _ = _coarse(g, inside, small, samples, seed, max_bright=bright)
        errors[name] = float(np.abs(s_d.numpy() - i_d).mean() / i_d.mean())
    light = prefiltered.lighting(env, small)
    normals = torch.from_numpy(g["normal"][inside]).double().T
    fast_d = prefiltered.diffuse_shading(normals, light.irradiance, light.lights).T
    errors["prefiltered"] = float(np.abs(fast_d.numpy() - i_d).mean() / i_d.mean())
    share = environments.sun_share(env, coarse_height)
    return _within(
        "coarse S_D",
        f"mean |S_D - I_D| / mean I_D under a sun map ({share:.0%} of its power in one coarse "
        f"texel; the paper's plain BRDF sampling: {errors['plain']:.3f}, the prefiltered "
        f"shading's SH and lights: {errors['prefiltered']:.3f})",
        errors["bright texels"],
        0.0,
        SUN_TOLERANCE,
    )


def furnace(
    mi, width: int, spp: int, samples: int, seed: int, coarse_height: int = 16
) -> list[Target]:
    """The checks over the sphere's interior pixels (``width`` px, Mitsuba at ``spp``,
    coarse shading with ``samples`` per pixel and lobe), each met or missed; the sun
    check's map is downsampled to ``coarse_height`` rows."""
    obj = white_sphere(FURNACE_ROUGHNESS)
    view = render.camera(FURNACE_DISTANCE, FURNACE_FOV)
    env = np.ones((*FURNACE_ENVIRONMENT, 3), np.float32)
    maps = render.shading_maps(mi, obj, env, view, width, spp, seed)
    g = render.g_buffers(obj, view, width)
    inside = (g["mask"] > 0) & (maps["coverage"] > 0.999)
    s_d, s_s = _coarse(g, inside, env[::2, ::2], samples, seed)
    i_d, i_s = maps["I_D"][inside], maps["I_S"][inside]
    rel = abs(float(s_s.mean()) - float(i_s.mean())) / float(i_s.mean())
    fast_d, fast_s = prefiltered.prefiltered_shading(
        torch.from_numpy(g["normal"][inside]).double(),
        torch.from_numpy(g["view_dir"][inside]).double(),
        torch.full((int(inside.sum()),), FURNACE_ROUGHNESS**2, dtype=torch.float64),
        prefiltered.lighting(env, env[::2, ::2]),
    )
    fast_rel = abs(float(fast_s.mean()) - float(i_s.mean())) / float(i_s.mean())
    return [
        _within(
            "Mitsuba I_D",
            "mean (convex white Lambertian, unit environment)",
            float(i_d.mean()),
            1.0,
            I_D_TOLERANCE,
        ),
        # Per-pixel Monte Carlo noise shrinks as 1 / sqrt(spp).
        _within(
            "Mitsuba I_D",
            "mean |I_D - 1| per pixel",
            float(np.abs(i_d - 1).mean()),
            0.0,
            spp**-0.5,
            why="1 / sqrt(spp) = ",
        ),
        _within("coarse S_D", "mean", float(s_d.mean()), 1.0, S_D_TOLERANCE),
        _within(
            "coarse S_S",
            "relative difference of its mean from Mitsuba's I_S (GGX albedo)",
            rel,
            0.0,
            GGX_TOLERANCE,
        ),
        # The map's SH by quadrature: exact but for the midpoint rule's rounding.
        _within("prefiltered S_D", "mean", float(fast_d.mean()), 1.0, PREFILTERED_S_D_TOLERANCE),
        _within(
            "prefiltered S_S",
            "relative difference of its mean from Mitsuba's I_S (GGX albedo)",
            fast_rel,
            0.0,
            GGX_TOLERANCE,
        ),
        sun_check(mi, width, spp, samples, coarse_height, seed),
    ]
