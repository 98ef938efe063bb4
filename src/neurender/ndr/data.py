"""NDR dataset generation (paper 3.2): the samples of one split.

One sample = one random object under one environment map, seen by the fixed camera of
:mod:`neurender.ndr.render`, stored in the format of :mod:`neurender.ndr.buffers`. Three
kinds of split: ``complex`` (SVBRDFs, a new random or user map per sample: the paper's
"complex material, varying illumination"; a share ``small_sun_fraction`` of the procedural
maps has a real outdoor sun), ``diffuse`` (specular albedo 0, one fixed built-in map
rotated never: the Real Shading setting) and ``sunlit`` (a test set only: complex
objects under real-world-like outdoor maps, every one with the small sun, see
:func:`neurender.ndr.environments.sunlit_environment`).

Every sample is determined by ``(seed, split, index)`` alone (:func:`neurender.rng.
stable_seed`), so samples render in any order, in any process.
"""

from __future__ import annotations

import logging
import math
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import torch

from neurender import io, lights
from neurender.ndr import environments, objects, pool, prefiltered, render, split_kind
from neurender.ndr.buffers import channels, lighting_rows
from neurender.ndr.shading import coarse_shading
from neurender.rng import stable_seed, torch_generator

log = logging.getLogger(__name__)

#: Offset of the noisy test render's seed from the reference's (independent noise).
NOISY_SEED_OFFSET = 7919


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


def _environment(
    cfg: dict, kind: str, part: str, rng: np.random.Generator
) -> tuple[np.ndarray, str]:
    """A sample's map ``(H, 2H, 3)`` and its name: the fixed probe for ``diffuse`` data, a
    real-world-like map for ``sunlit`` data, else a procedural or user map
    (:func:`environments.environment_for_sample`)."""
    height = cfg["environment_height"]
    if kind == "diffuse":
        return lights.procedural_probe(cfg["fixed_probe"], height), cfg["fixed_probe"]
    if kind == "sunlit":
        env = environments.sunlit_environment(rng, height)
        return environments.rotate_about_up(env, int(rng.integers(2 * height))), "sunlit"
    return environments.environment_for_sample(
        rng,
        height,
        _user_probes(cfg, part),
        cfg["user_probe_fraction"],
        cfg["small_sun_fraction"],
    )


def sample_scene(
    cfg: dict, split: str, index: int
) -> tuple[objects.ProceduralObject, np.ndarray, str, np.random.Generator]:
    """The object, map ``(H, 2H, 3)`` and map name of sample ``index`` of ``split``, and the
    sample's random generator (drawn from next for the render seed)."""
    kind, part = split_kind(split)
    rng = np.random.default_rng(stable_seed(cfg["seed"], "ndr", split, index))
    obj = objects.random_object(
        rng, tuple(cfg["primitives"]), cfg["edge_length"], diffuse_only=kind == "diffuse"
    )
    env, env_name = _environment(cfg, kind, part, rng)
    return obj, env, env_name, rng


def coarse_lighting(cfg: dict, env: np.ndarray) -> torch.Tensor | prefiltered.MapLighting:
    """What the coarse shading reads of ``env`` ``(H, 2H, 3)``, made once per map: the map
    downsampled to ``coarse_height`` rows (``coarse_shading: importance``), or the SH of
    ``env`` itself, the downsampled map's GGX-prefiltered copies and its bright texels as
    lights (``prefiltered``, :func:`neurender.ndr.prefiltered.lighting`)."""
    small = environments.resize_latlong(env, cfg["coarse_height"])
    if cfg["coarse_shading"] == "prefiltered":
        return prefiltered.lighting(env, small)
    return torch.from_numpy(small)


def coarse_maps(
    cfg: dict,
    g: dict[str, np.ndarray],
    env: np.ndarray,
    *key,
    lighting: torch.Tensor | prefiltered.MapLighting | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """``S_D`` and ``S_S`` ``(W, W, 3)`` float32 of the G-buffers ``g`` under ``env``
    (0 off the object) by the estimator ``coarse_shading`` names, from ``lighting``
    (:func:`coarse_lighting` of ``env``, made here when not given): ``importance``
    (:mod:`neurender.ndr.shading`: ``coarse_samples`` per pixel and lobe, at most
    ``bright_texels`` texels sampled explicitly; ``key``, e.g. split and index, seeds the
    sample pattern) or ``prefiltered`` (:mod:`neurender.ndr.prefiltered`; deterministic)."""
    lighting = coarse_lighting(cfg, env) if lighting is None else lighting
    width = cfg["width"]
    m = g["mask"].reshape(-1) > 0
    normals = torch.from_numpy(g["normal"].reshape(-1, 3)[m])
    view_dirs = torch.from_numpy(g["view_dir"].reshape(-1, 3)[m])
    alpha = torch.from_numpy(g["roughness"].reshape(-1)[m] ** 2)
    if cfg["coarse_shading"] == "prefiltered":
        sd, ss = prefiltered.prefiltered_shading(
            normals.double(), view_dirs.double(), alpha.double(), lighting
        )
    else:
        sd, ss = coarse_shading(
            normals,
            view_dirs,
            alpha,
            lighting,
            cfg["coarse_samples"],
            torch_generator(cfg["seed"], "ndr-coarse", *key),
            max_bright=cfg["bright_texels"],
        )
    s_d = np.zeros((width * width, 3), np.float32)
    s_s = np.zeros((width * width, 3), np.float32)
    s_d[m], s_s[m] = sd.numpy(), ss.numpy()
    return s_d.reshape(width, width, 3), s_s.reshape(width, width, 3)


def sample_channels(
    g: dict[str, np.ndarray], s_d: np.ndarray, s_s: np.ndarray, maps: dict[str, np.ndarray]
) -> dict[str, np.ndarray]:
    """A sample's EXR channels from its G-buffers, coarse shading and ground truth."""
    out = {}
    for group, image in (
        ("N", g["normal"]),
        ("R", g["roughness"]),
        ("D", g["depth"]),
        ("A_D", g["albedo_diffuse"]),
        ("A_S", g["albedo_specular"]),
        ("S_D", s_d),
        ("S_S", s_s),
        ("I_D", maps["I_D"]),
        ("I_S", maps["I_S"]),
        ("mask", g["mask"]),
    ):
        out.update(channels(group, image))
    return out


def make_sample(
    cfg: dict, split: str, index: int, mi, env_shift: int = 0
) -> tuple[dict, np.ndarray, dict]:
    """Render one sample: ``(EXR channels, SH features (75,), manifest row)``.

    ``env_shift`` turns the sample's map about +y by that many columns (relighting the same
    object for the paper's Fig. 3 (d)); 0 is the sample as stored. The manifest row holds
    the sample's statistics and its timings in seconds on one core.
    """
    kind, part = split_kind(split)
    start = time.perf_counter()
    obj, env, env_name, rng = sample_scene(cfg, split, index)
    env = environments.rotate_about_up(env, env_shift)
    view = render.camera(cfg["camera_distance"], cfg["fov"])
    width = cfg["width"]
    g = render.g_buffers(obj, view, width)
    spp = cfg["reference_spp"] if part == "test" else cfg["spp"]
    render_seed = int(rng.integers(2**30))
    specular = kind != "diffuse"  # complex and sunlit objects have SVBRDFs
    tic = time.perf_counter()
    maps = render.shading_maps(mi, obj, env, view, width, spp, render_seed, specular)
    render_seconds = time.perf_counter() - tic

    tic = time.perf_counter()
    lighting = coarse_lighting(cfg, env)
    lighting_seconds = time.perf_counter() - tic
    tic = time.perf_counter()
    s_d, s_s = coarse_maps(cfg, g, env, split, index, lighting=lighting)
    coarse_seconds = time.perf_counter() - tic
    out = sample_channels(g, s_d, s_s, maps)
    noisy_seconds = math.nan
    if part == "test":
        tic = time.perf_counter()
        noisy = render.shading_maps(
            mi, obj, env, view, width, cfg["spp"], render_seed + NOISY_SEED_OFFSET, specular
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
        "coarse_seconds": coarse_seconds,  # per image, the map's lighting made
        "coarse_lighting_seconds": lighting_seconds,  # once per map (a renderer's view)
        "coarse_shading": cfg["coarse_shading"],
    }
    return out, environments.sh_features(env), row


def write_sample(mi, cfg: dict, split: str, index: int, folder: str) -> tuple[np.ndarray, dict]:
    """Render sample ``index`` of ``split`` into ``folder``; its SH vector and manifest row."""
    out, light, row = make_sample(cfg, split, index, mi)
    io.write_exr(Path(folder) / row["file"], out)
    return light, row


def generate_split(
    cfg: dict, split: str, count: int, folder: str, manifest: str, lighting: str, workers: int
) -> None:
    """Render ``count`` samples of ``split`` into ``folder`` and write the manifest and SH
    lighting CSVs. The user's maps (complex splits) are all checked first
    (:func:`environments.check_user_probes`).

    With ``workers > 1`` samples render in that many forked single-threaded processes (at
    64 px one process per core is faster than Dr.Jit's threads); a process that already
    loaded Dr.Jit renders in-process instead, because its thread pool does not survive a
    fork (and spawn would re-run a Snakemake script's top level). A sample that fails ends
    the job with its error and traceback (see :mod:`neurender.ndr.pool`).
    """
    if split_kind(split)[0] == "complex" and cfg["user_probes_dir"]:
        environments.check_user_probes(cfg["user_probes_dir"], cfg["environment_height"])
    Path(folder).mkdir(parents=True, exist_ok=True)
    if workers > 1 and "drjit" in sys.modules:
        log.warning("Dr.Jit already loaded in this process: rendering %s in-process", split)
        workers = 1
    tasks = [(cfg, split, i, folder) for i in range(count)]
    results = pool.render_all(write_sample, tasks, cfg["device"], workers, f"ndr {split}")
    rows = [row for _, row in results]
    sh_rows = [r for light, row in results for r in lighting_rows(row["sample"], light)]
    io.write_csv(lighting, pd.DataFrame(sh_rows))
    io.write_csv(manifest, pd.DataFrame(rows))
    log.info(
        "%s: %d samples, %.2f s each on one core",
        split,
        count,
        np.mean([r["seconds"] for r in rows]) if rows else math.nan,
    )
