"""White-furnace checks of the NDR ground truth and coarse shading.

A convex white object under a constant unit environment reflects exactly 1 diffusely
(``I_D = 1`` everywhere: no occlusion on a convex shape, the cosine integral over pi is 1),
and its specular map is the GGX directional albedo, which Mitsuba's ``roughconductor`` and
our coarse-shading estimator compute independently. Each check is a
:class:`neurender.tables.Target` (subject ``Mitsuba I_D``, ``coarse S_D`` ...).
"""

from __future__ import annotations

import numpy as np
import torch
import trimesh

from neurender.ndr import render
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


def white_sphere(roughness: float) -> ProceduralObject:
    """A unit sphere (icosphere, 20,480 faces) with uniform ``roughness`` and white albedos."""
    mesh = trimesh.creation.icosphere(subdivisions=5)
    v = np.asarray(mesh.vertices, np.float32)
    ones = np.ones_like(v)
    return ProceduralObject(
        v, np.asarray(mesh.faces, np.int32), ones, ones, np.full(len(v), roughness, np.float32), 1
    )


def _within(
    subject: str, what: str, measured: float, expected: float, tol: float, why: str = ""
) -> Target:
    check = f"{what} within {why}{tol:.3g} of {expected:g}"
    return Target(subject, check, measured, abs(measured - expected) <= tol)


def furnace(mi, width: int, spp: int, samples: int, seed: int) -> list[Target]:
    """The checks over the sphere's interior pixels (``width`` px, Mitsuba at ``spp``,
    coarse shading with ``samples`` per pixel and lobe), each met or missed."""
    obj = white_sphere(FURNACE_ROUGHNESS)
    view = render.camera(FURNACE_DISTANCE, FURNACE_FOV)
    env = np.ones((*FURNACE_ENVIRONMENT, 3), np.float32)
    maps = render.shading_maps(mi, obj, env, view, width, spp, seed)
    g = render.g_buffers(obj, view, width)
    inside = (g["mask"] > 0) & (maps["coverage"] > 0.999)
    n = torch.from_numpy(g["normal"][inside])
    s_d, s_s = coarse_shading(
        n,
        torch.from_numpy(g["view_dir"][inside]),
        torch.full((len(n),), FURNACE_ROUGHNESS**2),
        torch.from_numpy(env[::2, ::2]),
        samples,
        torch_generator(seed, "furnace"),
    )
    i_d, i_s = maps["I_D"][inside], maps["I_S"][inside]
    rel = abs(float(s_s.mean()) - float(i_s.mean())) / float(i_s.mean())
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
    ]
