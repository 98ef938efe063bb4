"""White-furnace checks of the NDR ground truth and coarse shading.

A convex white object under a constant unit environment reflects exactly 1 diffusely
(``I_D = 1`` everywhere: no occlusion on a convex shape, the cosine integral over pi is 1),
and its specular map is the GGX directional albedo, which Mitsuba's ``roughconductor`` and
our coarse-shading estimator compute independently.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import torch
import trimesh

from neurender.ndr import render
from neurender.ndr.objects import ProceduralObject
from neurender.ndr.shading import coarse_shading
from neurender.rng import torch_generator


def white_sphere(roughness: float) -> ProceduralObject:
    """A unit sphere (icosphere, 20,480 faces) with uniform ``roughness`` and white albedos."""
    mesh = trimesh.creation.icosphere(subdivisions=5)
    v = np.asarray(mesh.vertices, np.float32)
    ones = np.ones_like(v)
    return ProceduralObject(
        v, np.asarray(mesh.faces, np.int32), ones, ones, np.full(len(v), roughness, np.float32), 1
    )


def furnace(mi, width: int, spp: int, roughness: float, samples: int, seed: int) -> pd.DataFrame:
    """Rows ``check, measured, expected, tolerance, passed`` over the sphere's interior pixels."""
    obj = white_sphere(roughness)
    view = render.camera(3.9, 30.0)
    env = np.ones((32, 64, 3), np.float32)
    maps = render.shading_maps(mi, obj, env, view, width, spp, seed)
    g = render.g_buffers(obj, view, width)
    inside = (g["mask"] > 0) & (maps["coverage"] > 0.999)
    n = torch.from_numpy(g["normal"][inside])
    s_d, s_s = coarse_shading(
        n,
        torch.from_numpy(g["view_dir"][inside]),
        torch.full((len(n),), roughness**2),
        torch.from_numpy(env[::2, ::2]),
        samples,
        torch_generator(seed, "furnace"),
    )
    i_d, i_s = maps["I_D"][inside], maps["I_S"][inside]
    rel = abs(float(s_s.mean()) - float(i_s.mean())) / float(i_s.mean())
    rows = [
        (
            "Mitsuba I_D mean (convex white Lambertian, unit environment)",
            float(i_d.mean()),
            1.0,
            0.01,
        ),
        # Per-pixel Monte Carlo noise shrinks as 1 / sqrt(spp).
        ("Mitsuba mean |I_D - 1| per pixel", float(np.abs(i_d - 1).mean()), 0.0, spp**-0.5),
        ("coarse S_D mean", float(s_d.mean()), 1.0, 1e-6),
        ("coarse S_S vs Mitsuba I_S, relative difference of means (GGX albedo)", rel, 0.0, 0.02),
    ]
    return pd.DataFrame(
        [
            {"check": c, "measured": m, "expected": e, "tolerance": t, "passed": abs(m - e) <= t}
            for c, m, e, t in rows
        ]
    )
