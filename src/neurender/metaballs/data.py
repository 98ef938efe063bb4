"""Metaball examples (thesis 4.1, 5.2): scenes, circle inputs and ray-marched targets as AB PNGs.

Files: ``{split}/example_XXXXX.png`` (AB images, :mod:`neurender.metaballs.ab`) and
``{split}_manifest.csv`` with one row per example: ``example, split, file, balls,
min_depth_separation`` (smallest centre-depth gap between two balls whose projected
circles overlap, world units; NaN if none overlap), ``coverage`` (fraction of pixels on
the surface) and ``seconds`` (ray marching).
"""

from __future__ import annotations

import time
from pathlib import Path

import pandas as pd
import torch
from tqdm import tqdm

from neurender import io
from neurender.metaballs import ab, inputs, raymarch, scenes
from neurender.plots import plt, save_figure
from neurender.rng import torch_generator


def min_overlap_depth_gap(scene: scenes.Scene, width: int) -> float:
    """Smallest centre-depth gap between two balls whose projected circles overlap."""
    centre = scenes.project(scene.centres, width)
    radius = inputs.projected_radius(scene, width)
    depth = scene.centres.norm(dim=1)
    overlap = torch.cdist(centre, centre) < radius[:, None] + radius[None, :]
    overlap.fill_diagonal_(False)
    gaps = (depth[:, None] - depth[None, :]).abs()[overlap]
    return float(gaps.min()) if len(gaps) else float("nan")


def example_scene(cfg: dict, split: str, index: int) -> scenes.Scene:
    """The (deterministic) scene of example ``index`` of ``split``, float32."""
    gen = torch_generator(cfg["seed"], "metaballs", split, index)
    lo, hi = cfg["balls"]
    count = int(torch.randint(lo, hi + 1, (1,), generator=gen))
    # float32 marching is twice as fast and still far below the 1e-3 depth tolerance.
    return scenes.sample_scene(count, tuple(cfg["radius"]), gen).to(torch.float32)


def generate_split(split: str, cfg: dict, threads: int, out_dir: str, manifest: str) -> None:
    """Write the AB examples of one split and their manifest.

    Args:
        cfg: ``seed``, ``width``, ``examples`` (per split), ``balls`` [min, max],
            ``radius`` [min, max].
    """
    torch.set_num_threads(threads)
    width = cfg["width"]
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for i in tqdm(range(cfg["examples"][split]), desc=f"metaballs {split}", mininterval=2.0):
        scene = example_scene(cfg, split, i)
        start = time.perf_counter()
        buffers = raymarch.render_gbuffers(scene, width)
        seconds = time.perf_counter() - start
        image = ab.pack(
            inputs.draw_inputs(scene, width), buffers.colour, buffers.depth, buffers.normal
        )
        file = out / f"example_{i:05d}.png"
        ab.write_ab(file, image)
        rows.append(
            {
                "example": i,
                "split": split,
                "file": file.name,
                "balls": len(scene),
                "min_depth_separation": min_overlap_depth_gap(scene, width),
                "coverage": float(buffers.mask.float().mean()),
                "seconds": seconds,
            }
        )
    io.write_csv(manifest, pd.DataFrame(rows))


def summarise(
    manifests: list[str], out_csv: str, out_png: str, example_dirs: list[str], count: int = 4
) -> None:
    """Tidy per-split statistics of the examples and a strip of AB images."""
    rows = []
    for path in manifests:
        m = io.read_csv(path, ["split", "balls", "coverage", "seconds"])
        split = str(m["split"].iloc[0])
        stats = {
            "examples": len(m),
            "balls_mean": m["balls"].mean(),
            "coverage_mean": m["coverage"].mean(),
            "min_depth_separation_median": m["min_depth_separation"].median(),
            "raymarch_seconds_per_example": m["seconds"].mean(),
        }
        rows += [
            {
                "method": "metaballs",
                "dataset": "examples",
                "model": "ray marcher",
                "split": split,
                "metric": k,
                "value": float(v),
            }
            for k, v in stats.items()
        ]
    io.write_csv(out_csv, pd.DataFrame(rows))
    files = sorted(Path(example_dirs[0]).glob("example_*.png"))[:count]
    fig, axes = plt.subplots(len(files), 1, figsize=(7.5, 2.6 * len(files)), squeeze=False)
    for ax, f in zip(axes[:, 0], files, strict=True):
        x = ab.read_ab(f)
        panels = [
            x["inputs"][:3],
            x["inputs"][3:].expand(3, -1, -1),
            x["colour"],
            x["depth"].expand(3, -1, -1),
            x["normal"],
        ]
        ax.imshow(torch.cat(panels, 2).permute(1, 2, 0).numpy())
        ax.set_title(
            f"{f.stem}: input colour | input depth | target colour | target depth | target normal",
            fontsize=7,
        )
        ax.axis("off")
    fig.tight_layout()
    save_figure(fig, out_png)
