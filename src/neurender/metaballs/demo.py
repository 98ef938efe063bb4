"""Deferred shading, an animated demo and timings (thesis 4.3, 5.4, 6.3, 7.2).

Shading (view space, y up, camera at the origin looking along +z): Lambert plus
Blinn-Phong from one directional light, plus ambient, applied to the G-buffers; the
background stays black. Colours are display values in [0, 1].
"""

from __future__ import annotations

import math
import time

import numpy as np
import pandas as pd
import torch

from neurender import io
from neurender.metaballs import raymarch, scenes
from neurender.metaballs.evaluate import silhouette_depth
from neurender.rng import torch_generator

LIGHT_DIR = (-0.4, 0.6, -0.7)  # towards the light, view space


def shade(buffers: torch.Tensor, ambient: float = 0.15, shininess: float = 40.0) -> torch.Tensor:
    """Lit image ``(3, W, W)`` from a ``(7, W, W)`` G-buffer stack in [0, 1]."""
    width = buffers.shape[-1]
    albedo, normal = buffers[:3], buffers[4:7] * 2 - 1
    normal = normal / normal.norm(dim=0, keepdim=True).clamp(min=1e-6)
    light = torch.tensor(LIGHT_DIR, dtype=buffers.dtype)
    light = light / light.norm()
    view = -scenes.pixel_rays(width, buffers.dtype).permute(2, 0, 1)
    half = (light[:, None, None] + view) / (light[:, None, None] + view).norm(dim=0, keepdim=True)
    diffuse = (normal * light[:, None, None]).sum(0).clamp(min=0)
    specular = (normal * half).sum(0).clamp(min=0) ** shininess
    lit = albedo * (ambient + (1 - ambient) * diffuse) + 0.4 * specular
    return (lit * silhouette_depth(buffers)).clamp(0, 1)


def animated_scene(base: scenes.Scene, frame: int, frames: int) -> scenes.Scene:
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
    return scenes.Scene(centres, base.radii, base.colours)


def _timed(fn, *args, repeats: int = 1):
    """Result of ``fn(*args)`` and its median wall time in seconds over ``repeats`` calls.

    On a GPU the clock stops only when queued kernels have finished, so the split between
    drawing inputs and the network is measured, not just their sum.
    """
    sync = torch.cuda.synchronize if torch.cuda.is_available() else lambda: None
    times = []
    for _ in range(repeats):
        sync()
        start = time.perf_counter()
        out = fn(*args)
        sync()
        times.append(time.perf_counter() - start)
    return out, float(np.median(times))


def run_demo(
    renderers: dict,
    cfg: dict,
    frames_out: str,
    timing_out: str,
    balls_out: str,
    balls_png: str,
    gif_out: str,
    strip_out: str,
    stability_out: str,
) -> None:
    """Animated sequence rendered by each network and by ray marching, with timings.

    Args:
        renderers: model name to a :class:`neurender.metaballs.model.MetaballRenderer`
            (``inputs(scene)`` then ``renderer((B, C, W, W)) -> (B, 7, W, W)``).
    """
    from neurender.plots import plt, save_figure

    width = cfg["width"]
    count = cfg["demo_frames"]
    gen = torch_generator(cfg["seed"], "metaballs", "demo")
    base = scenes.sample_scene(cfg["demo_balls"], tuple(cfg["radius"]), gen, margin=3.0).to(
        torch.float32
    )
    for r in renderers.values():  # warm-up: first calls allocate
        r(r.inputs(base)[None])
    rows, pictures, silhouettes = [], [], []
    for f in range(count):
        scene = animated_scene(base, f, count)
        truth, t_march = _timed(raymarch.render_gbuffers, scene, width)
        truth = truth.stack()
        lit, masks = [], []
        for name, r in renderers.items():
            x, t_in = _timed(r.inputs, scene)
            net, t_net = _timed(r, x[None])
            image, t_shade = _timed(shade, net[0])
            lit.append(image)
            masks.append(silhouette_depth(net[0]))
            rows.append(
                {
                    "frame": f,
                    "model": name,
                    "input_ms": 1e3 * t_in,
                    "network_ms": 1e3 * t_net,
                    "shading_ms": 1e3 * t_shade,
                    "raymarch_ms": 1e3 * t_march,
                }
            )
        pictures.append(torch.cat([*lit, shade(truth)], 2))
        silhouettes.append([*masks, silhouette_depth(truth)])
    timing = pd.DataFrame(rows)
    io.write_csv(frames_out, timing)
    frames_u8 = [io.to_uint8(p.permute(1, 2, 0).numpy()) for p in pictures]
    _write_gif(gif_out, frames_u8)
    strip = np.concatenate(frames_u8[:: max(1, count // 4)][:4], 0)
    io.write_png(strip_out, strip)

    # Temporal stability (thesis 7.2): fraction of pixels whose silhouette flips between frames.
    names = [*renderers, "ray marching"]
    flips = pd.DataFrame(
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
    fig, ax = plt.subplots(figsize=(5, 3))
    for n in names:
        ax.plot(flips.frame, flips[n], "s--" if n == "ray marching" else "o-", label=n)
    ax.set_xlabel("frame")
    ax.set_ylabel("silhouette pixels flipped since last frame")
    ax.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, stability_out)

    # Frame time against ball count: the network's cost does not depend on it.
    ball_rows = []
    for n in cfg["timing_balls"]:
        scene = scenes.sample_scene(
            n, tuple(cfg["radius"]), torch_generator(cfg["seed"], "timing", n)
        ).to(torch.float32)
        _, t_march = _timed(raymarch.render_gbuffers, scene, width, repeats=5)
        ball_rows.append({"balls": n, "model": "ray marcher", "ms_per_frame": 1e3 * t_march})
        for name, r in renderers.items():
            x, t_in = _timed(r.inputs, scene, repeats=5)
            _, t_net = _timed(r, x[None], repeats=5)
            ball_rows.append({"balls": n, "model": name, "ms_per_frame": 1e3 * (t_in + t_net)})
    balls = pd.DataFrame(ball_rows)
    fig, ax = plt.subplots(figsize=(5, 3))
    for name, part in balls.groupby("model", sort=False):
        label = name if name == "ray marcher" else f"{name}: inputs + network"
        ax.semilogy(
            part.balls, part.ms_per_frame, "s--" if name == "ray marcher" else "o-", label=label
        )
    ax.set_xlabel("number of balls")
    ax.set_ylabel("ms per frame")
    ax.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, balls_png)

    most = max(cfg["timing_balls"])
    march_ms = float(
        balls[(balls.balls == most) & (balls.model == "ray marcher")].ms_per_frame.iloc[0]
    )
    rows = []
    for name, part in timing.groupby("model", sort=False):
        summary = {
            "input_ms_per_frame": part.input_ms.mean(),
            "network_ms_per_frame": part.network_ms.mean(),
            "shading_ms_per_frame": part.shading_ms.mean(),
            "raymarch_ms_per_frame": part.raymarch_ms.mean(),
            "silhouette_flips": flips[name].mean(),
            "silhouette_flips_raymarch": flips["ray marching"].mean(),
            f"speedup_at_{most}_balls": march_ms
            / float(balls[(balls.balls == most) & (balls.model == name)].ms_per_frame.iloc[0]),
        }
        rows += [
            {
                "method": "metaballs",
                "dataset": "demo",
                "model": name,
                "split": "timing",
                "metric": k,
                "value": float(v),
            }
            for k, v in summary.items()
        ]
    rows += [
        {
            "method": "metaballs",
            "dataset": f"{int(r.balls)} balls",
            "model": r.model,
            "split": "timing",
            "metric": "ms_per_frame",
            "value": float(r.ms_per_frame),
        }
        for r in balls.itertuples()
    ]
    io.write_csv(timing_out, pd.DataFrame(rows))
    io.write_csv(balls_out, balls)


def _write_gif(path: str, frames: list[np.ndarray]) -> None:
    from PIL import Image

    images = [Image.fromarray(f) for f in frames]
    with io.atomic_path(path) as tmp:
        images[0].save(tmp, save_all=True, append_images=images[1:], duration=80, loop=0)
