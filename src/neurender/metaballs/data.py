"""Metaball examples (thesis 4.1, 5.2): scenes, circle inputs and ray-marched targets as AB PNGs.

Files: ``{split}/example_XXXXX.png`` (AB images, :mod:`neurender.metaballs.ab`),
``{split}_manifest.csv`` with one row per example: ``example, split, file, balls,
min_depth_separation`` (smallest centre-depth gap between two balls whose projected
circles overlap, world units; NaN if none overlap), ``coverage`` (fraction of pixels on
the surface) and ``seconds`` (ray marching on one core), and ``{split}_balls.csv`` with one
row per ball: ``example, ball, x, y, z`` (view space), ``radius, red, green, blue``.
"""

from __future__ import annotations

import time
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
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


BALL_COLUMNS = ["example", "ball", "x", "y", "z", "radius", "red", "green", "blue"]


def ball_rows(example: int, scene: scenes.Scene) -> list[dict]:
    """One :data:`BALL_COLUMNS` row per ball of an example's scene."""
    values = torch.cat([scene.centres, scene.radii[:, None], scene.colours], 1).double()
    return [
        {"example": example, "ball": b, **dict(zip(BALL_COLUMNS[2:], v, strict=True))}
        for b, v in enumerate(values.tolist())
    ]


def read_scenes(path: str | Path) -> dict[int, scenes.Scene]:
    """The float32 scene of every example in a ``{split}_balls.csv`` table."""
    table = io.read_csv(path, BALL_COLUMNS)
    out = {}
    for example, rows in table.sort_values(["example", "ball"]).groupby("example"):
        values = torch.tensor(rows[BALL_COLUMNS[2:]].to_numpy(), dtype=torch.float32)
        out[int(example)] = scenes.Scene(values[:, :3], values[:, 3], values[:, 4:])
    return out


def make_example(cfg: dict, split: str, index: int, out_dir: Path) -> tuple[dict, list[dict]]:
    """Ray-march one example, write its AB image; its manifest row and ball rows."""
    width = cfg["width"]
    scene = example_scene(cfg, split, index)
    start = time.perf_counter()
    buffers = raymarch.render_gbuffers(scene, width)
    seconds = time.perf_counter() - start
    image = ab.pack(inputs.draw_inputs(scene, width), buffers.colour, buffers.depth, buffers.normal)
    file = out_dir / f"example_{index:05d}.png"
    ab.write_ab(file, image)
    row = {
        "example": index,
        "split": split,
        "file": file.name,
        "balls": len(scene),
        "min_depth_separation": min_overlap_depth_gap(scene, width),
        "coverage": float(buffers.mask.float().mean()),
        "seconds": seconds,
    }
    return row, ball_rows(index, scene)


def _single_threaded() -> None:
    torch.set_num_threads(1)


def _make_example(args: tuple[dict, str, int, Path]) -> tuple[dict, list[dict]]:
    return make_example(*args)


def generate_split(
    split: str, cfg: dict, workers: int, out_dir: str, manifest: str, balls_csv: str
) -> None:
    """Write the AB examples of one split, their manifest and their balls.

    Examples are ray-marched by ``workers`` forked single-threaded processes (small
    per-ray tensors scale across processes, not across torch threads).

    Args:
        cfg: ``seed``, ``width``, ``examples`` (per split), ``balls`` [min, max],
            ``radius`` [min, max].
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    jobs = [(cfg, split, i, out) for i in range(cfg["examples"][split])]
    if workers > 1:
        pool = ProcessPoolExecutor(
            workers, mp_context=get_context("fork"), initializer=_single_threaded
        )
        results = pool.map(_make_example, jobs, chunksize=8)
    else:
        pool = None
        _single_threaded()
        results = map(_make_example, jobs)
    rows, balls = [], []
    try:
        for row, ball in tqdm(results, total=len(jobs), desc=f"metaballs {split}", mininterval=5):
            rows.append(row)
            balls += ball
    finally:
        if pool is not None:
            pool.shutdown(cancel_futures=True)
    io.write_csv(balls_csv, pd.DataFrame(balls, columns=BALL_COLUMNS))
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
