"""Metaball examples (thesis 4.1, 5.2): scenes, circle inputs and ray-marched targets as AB PNGs.

Files: ``{split}/example_XXXXX.png`` (AB images, :mod:`neurender.metaballs.ab`),
``{split}_manifest.csv`` with one row per example: ``example, split, file, balls,
min_depth_separation`` (smallest centre-depth gap between two balls whose projected
circles overlap, world units; NaN if none overlap), ``coverage`` (fraction of pixels on
the surface) and ``seconds`` (ray marching on one core), and ``{split}_balls.csv`` with one
row per ball: ``example, ball, x, y, z`` (view space), ``radius, red, green, blue``.
"""

from __future__ import annotations

import dataclasses
import math
import time
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from pathlib import Path

import numpy as np
import pandas as pd
import torch
from scipy.spatial import cKDTree
from tqdm import tqdm

from neurender import io
from neurender.metaball import INVERSE_SQUARE, Kernel, Scene, kernel_from_config
from neurender.metaballs import ab, families, inputs, raymarch, scenes
from neurender.rng import torch_generator


def min_overlap_depth_gap(scene: Scene, width: int) -> float:
    """Smallest centre-depth gap between two balls whose projected circles overlap (the
    candidate pairs from a k-d tree of the projected centres: no ``B x B`` matrix)."""
    centre = scenes.project(scene.centres, width).double().numpy()
    radius = inputs.projected_radius(scene, width).double().numpy()
    depth = scene.centres.norm(dim=1).double().numpy()
    pairs = cKDTree(centre).query_pairs(2 * float(radius.max()), output_type="ndarray")
    i, j = pairs.T
    overlap = np.hypot(*(centre[i] - centre[j]).T) < radius[i] + radius[j]
    gaps = np.abs(depth[i] - depth[j])[overlap]
    return float(gaps.min()) if len(gaps) else float("nan")


def example_scene(cfg: dict, split: str, index: int) -> Scene:
    """The (deterministic) scene of example ``index`` of ``split``, float32.

    Args:
        cfg: ``seed``, ``balls`` [min, max] (count), ``kernel`` (config),
            ``family``: ``thesis`` (:func:`neurender.metaballs.scenes.sample_scene`, a
            count uniform in ``balls``, ``radius`` [min, max] in world units) or
            ``cluster`` (:func:`neurender.metaballs.families.cluster` at ``packing``, a
            count log-uniform in ``balls``: as many scenes of 10^2 to 10^3 balls as of
            10^3 to 10^4).
    """
    gen = torch_generator(cfg["seed"], "metaballs", split, index)
    lo, hi = cfg["balls"]
    kernel = kernel_from_config(cfg["kernel"])
    if cfg["family"] == "cluster":
        u = float(torch.rand((), generator=gen, dtype=torch.float64))
        count = round(math.exp(math.log(lo) + u * (math.log(hi) - math.log(lo))))
        scene = families.cluster(count, gen, packing=cfg["packing"], kernel=kernel)
    else:
        count = int(torch.randint(lo, hi + 1, (1,), generator=gen))
        scene = scenes.sample_scene(count, tuple(cfg["radius"]), gen)
        scene = dataclasses.replace(scene, kernel=kernel)
    # float32 marching is twice as fast and still far below the 1e-3 depth tolerance.
    return scene.to(torch.float32)


BALL_COLUMNS = ["example", "ball", "x", "y", "z", "radius", "red", "green", "blue"]


def ball_rows(example: int, scene: Scene) -> list[dict]:
    """One :data:`BALL_COLUMNS` row per ball of an example's scene."""
    values = torch.cat([scene.centres, scene.radii[:, None], scene.colours], 1).double()
    return [
        {"example": example, "ball": b, **dict(zip(BALL_COLUMNS[2:], v, strict=True))}
        for b, v in enumerate(values.tolist())
    ]


def read_scenes(path: str | Path, kernel: Kernel = INVERSE_SQUARE) -> dict[int, Scene]:
    """The float32 scene of every example in a ``{split}_balls.csv`` table, its balls'
    field ``kernel`` (the config's, which the table does not hold)."""
    table = io.read_csv(path, BALL_COLUMNS)
    out = {}
    for example, rows in table.sort_values(["example", "ball"]).groupby("example"):
        values = torch.tensor(rows[BALL_COLUMNS[2:]].to_numpy(), dtype=torch.float32)
        out[int(example)] = Scene(values[:, :3], values[:, 3], values[:, 4:], kernel)
    return out


def make_example(cfg: dict, split: str, index: int, out_dir: Path) -> tuple[dict, list[dict]]:
    """Ray-march one example, write its AB image; its manifest row and ball rows."""
    width = cfg["width"]
    scene = example_scene(cfg, split, index)
    start = time.perf_counter()
    buffers = raymarch.render_gbuffers(scene, width)
    seconds = time.perf_counter() - start
    image = ab.pack(inputs.draw_inputs(scene, width), buffers.stack())
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
    cfg: dict, split: str, count: int, workers: int, out_dir: str | Path
) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Write the ``count`` AB examples of one split to ``out_dir``; their manifest and
    their balls (:data:`BALL_COLUMNS`) as tables.

    Examples are ray-marched by ``workers`` forked single-threaded processes (small
    per-ray tensors scale across processes, not across torch threads).

    Args:
        cfg: ``seed``, ``width`` and the keys of :func:`example_scene`.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    jobs = [(cfg, split, i, out) for i in range(count)]
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
    return pd.DataFrame(rows), pd.DataFrame(balls, columns=BALL_COLUMNS)
