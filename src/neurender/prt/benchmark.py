"""Ray-throughput benchmark of the DeepPRT ground-truth stage against bare Embree.

Measures, on one default frame: (1) the stage's rays/s end to end (direction sets,
normals, ray set-up, Embree, SH projection, glossy), (2) the limit: bare Embree OCCLUDED
calls on exactly the same rays, pre-sorted by origin and split over the same threads, and
(3) seconds per frame at paper scale (n = 256, 1024 directions) beside the paper's
39.6 s (diffuse) / 49.7 s (glossy).
"""

from __future__ import annotations

import time

import numpy as np
import pandas as pd
import scipy.ndimage

from neurender import io
from neurender.geometry import grid_faces, grid_normals
from neurender.prt import transfer
from neurender.prt.frames import ray_offset
from neurender.raytrace import occluded
from neurender.rng import stable_seed
from neurender.tables import threshold, tidy_rows


def _seconds(fn) -> float:
    start = time.perf_counter()
    fn()
    return time.perf_counter() - start


def stage_vs_embree(
    positions: np.ndarray,
    cfg: dict,
    threads: int,
    directions: int,
    light: np.ndarray | None,
    repeats: int = 5,
):
    """Seconds per frame of the stage and of bare Embree on the same rays, and the ray count."""
    n_bands = cfg["n_bands"]
    faces = grid_faces(positions.shape[0])
    offset = ray_offset(positions, cfg["ray_offset"])
    seed = stable_seed(cfg["seed"], "benchmark", directions)

    def stage():
        rng = np.random.default_rng(seed)
        sets = transfer.DirectionSets(cfg["direction_sets"], directions, n_bands, rng)
        return transfer.frame_transfer(positions, faces, sets, rng, offset, light, threads)

    rays = stage()[3]
    # The same rays, prepared outside the timing and sorted by origin: the limit is Embree alone.
    rng = np.random.default_rng(seed)
    sets = transfer.DirectionSets(cfg["direction_sets"], directions, n_bands, rng)
    p = positions.reshape(-1, 3).astype(np.float32)
    normals = grid_normals(positions).reshape(-1, 3).astype(np.float32)
    assignment = rng.integers(0, sets.dirs.shape[0], len(p))
    jobs = transfer.direction_jobs(assignment, sets.dirs.shape[0])
    rays_of = [
        transfer.upper_hemisphere_rays(p[rows], normals[rows], sets.dirs[s], offset)
        for s, rows in jobs
    ]
    # Sorted by origin (vertex index), the most coherent order for Embree.
    vertex = np.concatenate(
        [np.repeat(rows, r[1].sum(1)) for (_, rows), r in zip(jobs, rays_of, strict=True)]
    )
    order = np.argsort(vertex, kind="stable")
    origins = np.ascontiguousarray(np.concatenate([r[2] for r in rays_of])[order])
    dirs = np.ascontiguousarray(np.concatenate([r[3] for r in rays_of])[order])
    if len(origins) != rays:
        raise RuntimeError(f"benchmark rays {len(origins)} differ from the stage's {rays}")
    # Best of several alternating runs: a busy moment of the machine hits neither side alone.
    t_stage = t_embree = np.inf
    for _ in range(repeats):
        t_stage = min(t_stage, _seconds(stage))
        t_embree = min(t_embree, _seconds(lambda: occluded(p, faces, origins, dirs, threads)))
    return t_stage, t_embree, rays


def run_benchmark(
    seq_path: str, light: np.ndarray, cfg: dict, threads: int, out: str
) -> pd.DataFrame:
    """Write the benchmark as tidy CSV (``method, dataset, model, split, metric, value``)."""
    seq = io.load_npz(seq_path)
    frame = seq["train_positions"][0].astype(np.float64)
    n = frame.shape[0]
    rows = []

    def add(setting: str, metric: str, value: float) -> None:
        rows.extend(
            tidy_rows("prt", setting, "ray-traced ground truth", "benchmark", {metric: value})
        )

    setting = f"n={n}, {cfg['directions']} dirs, {threads} threads"
    t_stage, t_embree, rays = stage_vs_embree(frame, cfg, threads, cfg["directions"], light)
    add(setting, "stage_rays_per_s", rays / t_stage)
    add(setting, "embree_rays_per_s", rays / t_embree)
    add(setting, "stage_fraction_of_embree", t_embree / t_stage)
    target = threshold("prt", "embree_fraction")
    add(setting, "target_fraction", target)
    add(setting, "target_met", float(t_embree / t_stage >= target))
    add(setting, "seconds_per_frame", t_stage)
    if cfg["benchmark_paper_scale"]:
        big = np.stack([scipy.ndimage.zoom(frame[..., c], 256 / n, order=3) for c in range(3)], -1)
        setting = f"paper scale n=256, 1024 dirs, {threads} threads"
        for label, lgt in (("diffuse", None), ("diffuse+glossy", light)):
            t_stage, t_embree, rays = stage_vs_embree(big, cfg, threads, 1024, lgt, repeats=1)
            add(setting, f"seconds_per_frame_{label}", t_stage)
            add(setting, f"stage_rays_per_s_{label}", rays / t_stage)
    frame_out = pd.DataFrame(rows)
    io.write_csv(out, frame_out)
    return frame_out
