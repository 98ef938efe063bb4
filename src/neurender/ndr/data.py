"""NDR dataset generation (paper 3.2) and loading.

One sample = one random object under one environment map, seen by the fixed camera of
:mod:`neurender.ndr.render`, stored as a float32 OpenEXR with named channels (rows top
first, linear values, view-space vectors):

``N.X N.Y N.Z`` normals, ``R`` roughness, ``D`` depth, ``A_D.{R,G,B}`` and
``A_S.{R,G,B}`` albedos, ``S_D.*`` and ``S_S.*`` coarse shading, ``I_D.*`` and ``I_S.*``
ray-traced shading maps, ``mask`` (pixel centre on the object). Test samples add
``I_D_noisy.*`` and ``I_S_noisy.*``: an independent render at the *training* sample count,
for the noise floor (the test's ``I_D``/``I_S`` use ``reference_spp``).

A split's lighting is a tidy CSV ``sample, coefficient, channel, value`` of the 5-band SH
(25 x RGB) of each sample's map. Two kinds of split: ``complex`` (SVBRDFs, a new random or
user map per sample: paper's "complex material, varying illumination") and ``diffuse``
(specular albedo 0, one fixed built-in map rotated never: the Real Shading setting).
"""

from __future__ import annotations

import logging
import math
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from multiprocessing import get_context
from pathlib import Path

import numpy as np
import pandas as pd
import torch
from tqdm import tqdm

from neurender import io, lights
from neurender.mitsuba_setup import INSTALL_HINT
from neurender.ndr import environments, objects, render
from neurender.ndr.shading import coarse_shading
from neurender.rng import stable_seed, torch_generator

log = logging.getLogger(__name__)

RGB = ("R", "G", "B")
XYZ = ("X", "Y", "Z")
BUFFERS = {  # EXR channel groups and their channel suffixes
    "N": XYZ,
    "R": (),
    "D": (),
    "A_D": RGB,
    "A_S": RGB,
    "S_D": RGB,
    "S_S": RGB,
    "I_D": RGB,
    "I_S": RGB,
    "mask": (),
}
NOISY = {"I_D_noisy": RGB, "I_S_noisy": RGB}


def split_kind(split: str) -> tuple[str, str]:
    """``"diffuse_test"`` -> ``("diffuse", "test")``; ``"train"`` -> ``("complex", "train")``."""
    kind, _, part = split.rpartition("_")
    if part not in ("train", "val", "test") or kind not in ("", "diffuse"):
        raise ValueError(f"NDR split {split!r}: expected [diffuse_]train|val|test")
    return kind or "complex", part


def channels(group: str, image: np.ndarray) -> dict[str, np.ndarray]:
    """EXR channels of one buffer group: ``(H, W)`` or ``(H, W, C)`` -> name -> ``(H, W)``."""
    suffixes = BUFFERS.get(group) or NOISY.get(group, ())
    if not suffixes:
        return {group: image}
    return {f"{group}.{s}": image[..., i] for i, s in enumerate(suffixes)}


def _user_probes(cfg: dict, part: str) -> list[Path]:
    """User maps for a split: every fifth (sorted; the last one if there are fewer than
    five) is held out for the test split, the rest light train and val. A single map
    lights every split."""
    if not cfg["user_probes_dir"]:
        return []
    found = environments.user_probes(cfg["user_probes_dir"])
    if len(found) < 2:
        return found
    held_out = set(range(4, len(found), 5)) or {len(found) - 1}
    return [p for i, p in enumerate(found) if (i in held_out) == (part == "test")]


def make_sample(
    cfg: dict, split: str, index: int, mi, env_shift: int = 0
) -> tuple[dict, np.ndarray, dict]:
    """Render one sample: ``(EXR channels, SH features (75,), manifest row)``.

    ``env_shift`` turns the sample's map about +y by that many columns (relighting the same
    object for the paper's Fig. 3 (d)); 0 is the sample as stored.
    """
    kind, part = split_kind(split)
    rng = np.random.default_rng(stable_seed(cfg["seed"], "ndr", split, index))
    start = time.perf_counter()
    obj = objects.random_object(
        rng, tuple(cfg["primitives"]), cfg["edge_length"], diffuse_only=kind == "diffuse"
    )
    if kind == "diffuse":
        env = lights.procedural_probe(cfg["fixed_probe"], cfg["environment_height"])
        env_name = cfg["fixed_probe"]
    else:
        env, env_name = environments.environment_for_sample(
            rng,
            cfg["environment_height"],
            _user_probes(cfg, part),
            cfg["user_probe_fraction"],
        )
    env = environments.rotate_about_up(env, env_shift)
    view = render.camera(cfg["camera_distance"], cfg["fov"])
    width = cfg["width"]
    g = render.g_buffers(obj, view, width)
    spp = cfg["reference_spp"] if part == "test" else cfg["spp"]
    render_seed = int(rng.integers(2**30))
    tic = time.perf_counter()
    maps = render.shading_maps(mi, obj, env, view, width, spp, render_seed, kind == "complex")
    render_seconds = time.perf_counter() - tic

    m = g["mask"].reshape(-1) > 0
    small = torch.from_numpy(environments.resize_latlong(env, cfg["coarse_height"]))
    tic = time.perf_counter()
    s_d = np.zeros((width * width, 3), np.float32)
    s_s = np.zeros((width * width, 3), np.float32)
    sd, ss = coarse_shading(
        torch.from_numpy(g["normal"].reshape(-1, 3)[m]),
        torch.from_numpy(g["view_dir"].reshape(-1, 3)[m]),
        torch.from_numpy(g["roughness"].reshape(-1)[m] ** 2),
        small,
        cfg["coarse_samples"],
        torch_generator(cfg["seed"], "ndr-coarse", split, index),
    )
    s_d[m], s_s[m] = sd.numpy(), ss.numpy()
    coarse_seconds = time.perf_counter() - tic
    out = {}
    for group, image in (
        ("N", g["normal"]),
        ("R", g["roughness"]),
        ("D", g["depth"]),
        ("A_D", g["albedo_diffuse"]),
        ("A_S", g["albedo_specular"]),
        ("S_D", s_d.reshape(width, width, 3)),
        ("S_S", s_s.reshape(width, width, 3)),
        ("I_D", maps["I_D"]),
        ("I_S", maps["I_S"]),
        ("mask", g["mask"]),
    ):
        out.update(channels(group, image))
    noisy_seconds = math.nan
    if part == "test":
        tic = time.perf_counter()
        noisy = render.shading_maps(
            mi, obj, env, view, width, cfg["spp"], render_seed + 7919, kind == "complex"
        )
        noisy_seconds = time.perf_counter() - tic
        out.update(channels("I_D_noisy", noisy["I_D"]))
        out.update(channels("I_S_noisy", noisy["I_S"]))
    row = {
        "sample": index,
        "file": f"{index:05d}.exr",
        "primitives": obj.n_primitives,
        "triangles": len(obj.faces),
        "environment": env_name,
        "coverage": float(g["mask"].mean()),
        "spp": spp,
        "seconds": time.perf_counter() - start,
        "render_seconds": render_seconds,  # Mitsuba, both maps, at `spp`, one core
        "train_spp_render_seconds": noisy_seconds if part == "test" else render_seconds,
        "coarse_seconds": coarse_seconds,
    }
    return out, environments.sh_features(env), row


_WORKER: dict = {}


def _init_worker(device: str, threads: int) -> None:
    from neurender.mitsuba_setup import require_mitsuba

    mi, dr = require_mitsuba(device)
    dr.set_thread_count(threads)
    _WORKER["mi"] = mi
    torch.set_num_threads(threads)


def _work(args: tuple[dict, str, int, str]) -> tuple[np.ndarray, dict]:
    cfg, split, index, folder = args
    out, light, row = make_sample(cfg, split, index, _WORKER["mi"])
    io.write_exr(Path(folder) / row["file"], out)
    return light, row


def generate_split(
    cfg: dict, split: str, count: int, folder: str, manifest: str, lighting: str, workers: int
) -> None:
    """Render ``count`` samples of ``split`` into ``folder`` and write the manifest and SH
    lighting CSVs.

    With ``workers > 1`` samples render in that many forked single-threaded processes (at
    64 px one process per core is faster than Dr.Jit's threads); a process that already
    loaded Dr.Jit renders in-process instead, because its thread pool does not survive a
    fork (and spawn would re-run a Snakemake script's top level).
    """
    Path(folder).mkdir(parents=True, exist_ok=True)
    jobs = [(cfg, split, i, folder) for i in range(count)]
    if workers > 1 and "drjit" in sys.modules:
        log.warning("Dr.Jit already loaded in this process: rendering %s in-process", split)
        workers = 1
    if workers > 1:
        pool = ProcessPoolExecutor(
            workers,
            mp_context=get_context("fork"),
            initializer=_init_worker,
            initargs=(cfg["device"], 1),
        )
        results = pool.map(_work, jobs, chunksize=4)
    else:
        pool = None
        _init_worker(cfg["device"], 1)
        results = map(_work, jobs)
    rows, sh_rows = [], []
    try:
        for light, row in tqdm(results, total=count, desc=f"ndr {split}", mininterval=5):
            rows.append(row)
            sh_rows += [
                {
                    "sample": row["sample"],
                    "coefficient": k // 3,
                    "channel": RGB[k % 3],
                    "value": float(value),
                }
                for k, value in enumerate(light)
            ]
    except BrokenProcessPool as err:  # a worker died, e.g. Mitsuba or LLVM missing
        raise SystemExit(
            f"error: a rendering process for NDR split {split!r} failed ({err}); check that "
            f"Mitsuba runs here: {INSTALL_HINT}"
        ) from None
    finally:
        if pool is not None:
            pool.shutdown(cancel_futures=True)
    io.write_csv(lighting, pd.DataFrame(sh_rows))
    io.write_csv(manifest, pd.DataFrame(rows))
    log.info(
        "%s: %d samples, %.2f s each on one core",
        split,
        count,
        np.mean([r["seconds"] for r in rows]) if rows else math.nan,
    )
