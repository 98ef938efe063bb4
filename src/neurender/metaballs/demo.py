"""Deferred shading and an animated demo rendered by the networks and by ray marching
(thesis 4.3, 5.4, 7.2).

Shading (view space of :mod:`neurender.metaballs.scenes`: y up, camera at the origin
looking along +z): Lambert plus Blinn-Phong from one directional light, plus ambient,
applied to G-buffer stacks (:mod:`neurender.metaballs.gbuffers`); the background (by
depth) stays black. Colours are display values in [0, 1]. Times are milliseconds of wall
clock, medians of :func:`neurender.timing.timed`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping

import pandas as pd
import torch

from neurender.metaball import Scene, kernel_from_config
from neurender.metaballs import gbuffers, raymarch, scenes
from neurender.metaballs.renderer import MetaballRenderer
from neurender.rng import torch_generator
from neurender.timing import timed

LIGHT_DIR = (-0.4, 0.6, -0.7)  # towards the light, view space
#: The label of the ray marcher's silhouettes (:func:`silhouette_flips`).
RAY_MARCHING = "ray marching"
#: The timed parts of a demo frame, in :attr:`Sequence.timings`' column order.
PARTS = ("input", "network", "shading", "raymarch")


def shade(buffers: torch.Tensor, ambient: float = 0.15, shininess: float = 40.0) -> torch.Tensor:
    """Lit image ``(3, W, W)`` from a ``(7, W, W)`` G-buffer stack in [0, 1]."""
    width = buffers.shape[-1]
    albedo, normal = buffers[gbuffers.COLOUR], gbuffers.decoded_normals(buffers)
    normal = normal / normal.norm(dim=0, keepdim=True).clamp(min=1e-6)
    light = torch.tensor(LIGHT_DIR, dtype=buffers.dtype)
    light = light / light.norm()
    view = -scenes.pixel_rays(width, buffers.dtype).permute(2, 0, 1)
    half = (light[:, None, None] + view) / (light[:, None, None] + view).norm(dim=0, keepdim=True)
    diffuse = (normal * light[:, None, None]).sum(0).clamp(min=0)
    specular = (normal * half).sum(0).clamp(min=0) ** shininess
    lit = albedo * (ambient + (1 - ambient) * diffuse) + 0.4 * specular
    return (lit * gbuffers.silhouette_depth(buffers)).clamp(0, 1)


def demo_scene(cfg: Mapping) -> Scene:
    """The demo's float32 balls: ``demo_balls`` of ``radius`` [min, max], kept 3 units
    inside the depth range so that the animation stays in it, of the ``kernel`` (config)."""
    gen = torch_generator(cfg["seed"], "metaballs", "demo")
    scene = scenes.sample_scene(cfg["demo_balls"], tuple(cfg["radius"]), gen, margin=3.0)
    return dataclasses.replace(scene.to(torch.float32), kernel=kernel_from_config(cfg["kernel"]))


def animated_scene(base: Scene, frame: int, frames: int) -> Scene:
    """Balls bobbing on small circles while the camera orbits the scene's centre (about y)."""
    phase = 2 * math.pi * frame / frames
    pivot = torch.tensor([0.0, 0.0, 16.0], dtype=base.centres.dtype)
    k = torch.arange(len(base), dtype=base.centres.dtype)
    wobble = 0.6 * torch.stack(
        [torch.sin(phase + k), torch.cos(2 * phase + 0.5 * k), torch.zeros_like(k)], 1
    )
    angle = 0.5 * math.sin(phase)  # orbit +-29 degrees
    c, s = math.cos(angle), math.sin(angle)
    rot = torch.tensor([[c, 0, s], [0, 1, 0], [-s, 0, c]], dtype=base.centres.dtype)
    centres = (base.centres + wobble - pivot) @ rot.T + pivot
    return Scene(centres, base.radii, base.colours, base.kernel)


@dataclasses.dataclass
class Sequence:
    """The rendered demo: ``timings`` (one row per frame and model: ``frame, model,
    input_ms, network_ms, shading_ms, raymarch_ms``), ``pictures`` (one ``(3, W, (M + 1) W)``
    image per frame: each model's shading, then the ray marcher's) and ``silhouettes`` (per
    frame, each model's ``(W, W)`` silhouette by depth, then the ray marcher's)."""

    timings: pd.DataFrame
    pictures: list[torch.Tensor]
    silhouettes: list[list[torch.Tensor]]


def render_sequence(
    renderers: Mapping[str, MetaballRenderer], base: Scene, frames: int, width: int
) -> Sequence:
    """Animate ``base`` over ``frames`` frames; render, shade and time each frame with
    every network (inputs, network, shading) and with the ray marcher."""
    for r in renderers.values():  # warm-up: first calls allocate
        r(r.inputs(base)[None])
    rows, pictures, silhouettes = [], [], []
    for f in range(frames):
        scene = animated_scene(base, f, frames)
        truth, t_march = timed(raymarch.render_gbuffers, scene, width)
        truth = truth.stack()
        lit, masks = [], []
        for name, r in renderers.items():
            x, t_in = timed(r.inputs, scene)
            net, t_net = timed(r, x[None])
            image, t_shade = timed(shade, net[0])
            lit.append(image)
            masks.append(gbuffers.silhouette_depth(net[0]))
            times = (t_in, t_net, t_shade, t_march)
            rows.append(
                {"frame": f, "model": name}
                | {f"{part}_ms": 1e3 * t for part, t in zip(PARTS, times, strict=True)}
            )
        pictures.append(torch.cat([*lit, shade(truth)], 2))
        silhouettes.append([*masks, gbuffers.silhouette_depth(truth)])
    return Sequence(pd.DataFrame(rows), pictures, silhouettes)


def silhouette_flips(silhouettes: list[list[torch.Tensor]], names: list[str]) -> pd.DataFrame:
    """Temporal stability (thesis 7.2): per frame from the second on, the fraction of
    pixels whose silhouette flipped since the previous frame, one column per name."""
    return pd.DataFrame(
        [
            {
                "frame": f,
                **{
                    n: float((a ^ b).float().mean())
                    for n, a, b in zip(names, prev, cur, strict=True)
                },
            }
            for f, (prev, cur) in enumerate(zip(silhouettes[:-1], silhouettes[1:], strict=True), 1)
        ]
    )
