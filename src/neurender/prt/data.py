"""DeepPRT data stage: the functions behind the Snakemake rules of ``workflow/rules/prt.smk``.

Files (see README, "DeepPRT data"):

* ``probes/{probe}.exr`` lat-long light (R, G, B) and ``probes/{probe}_sh.csv`` its SH
  projection, tidy rows ``k, l, m, channel, value``.
* ``{object}/geometry_image.npz``: ``rest`` ``(n, n, 3)``, ``deltas`` ``(B, n, n, 3)``
  blendshape displacements, ``blendshapes`` names, ``uv``, ``source_vertices``,
  ``source_faces``, ``kind``; ``geometry_image.csv`` its statistics.
* ``{object}/sequence.npz``: per split ``{split}_positions`` ``(F, n, n, 3)`` and
  ``{split}_params`` ``(F, P)`` shape parameters; ``test_extrapolated`` ``(F,)``.
* ``{object}/{split}/frame_XXXX.exr``: channels ``P.x P.y P.z N.x N.y N.z`` (float32),
  ``T.00 ... T.{K-1}`` diffuse transfer and ``G.r.00 ... G.b.{K-1}`` glossy transferred
  radiance (float16); ``{split}_manifest.csv`` one row per frame.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

import numpy as np
import pandas as pd
from tqdm import tqdm

from neurender import io, lights, sh
from neurender.geometry import grid_faces
from neurender.plots import plt, save_figure
from neurender.prt import deform, objects, transfer
from neurender.prt.geometry_image import build_geometry_image, reconstruction_error
from neurender.rng import stable_seed
from neurender.shapes import BLENDSHAPES

log = logging.getLogger(__name__)

SPLITS = ("train", "val", "test")
COLOURS = ("r", "g", "b")


# ---------------------------------------------------------------- light probes


def make_probe(name: str, user_path: str | None, cfg: dict, exr_out: str, sh_out: str) -> None:
    """Build (or load) a light probe, write it as EXR and its SH projection as tidy CSV."""
    image = (
        lights.load_probe(user_path)
        if user_path
        else lights.procedural_probe(name, cfg["probe_height"])
    )
    coeffs = sh.project_latlong(image, cfg["n_bands"])
    rows = [
        {
            "k": k,
            "l": int(np.sqrt(k)),
            "m": k - int(np.sqrt(k)) * (int(np.sqrt(k)) + 1),
            "channel": c,
            "value": coeffs[k, i],
        }
        for k in range(coeffs.shape[0])
        for i, c in enumerate("RGB")
    ]
    lights.write_probe(exr_out, image)
    io.write_csv(sh_out, pd.DataFrame(rows))


def read_sh_light(path: str | Path) -> np.ndarray:
    """SH light ``(K, 3)`` from a probe's tidy CSV."""
    frame = io.read_csv(path, ["k", "channel", "value"])
    wide = frame.pivot(index="k", columns="channel", values="value")
    return wide[["R", "G", "B"]].to_numpy(np.float64)


# ---------------------------------------------------------------- geometry images


def make_geometry_image(
    name: str, user_path: str | None, cfg: dict, gim_out: str, stats_out: str
) -> None:
    """Parametrise the object's source mesh and resample it (and its blendshapes) on the grid."""
    start = time.perf_counter()
    n, seed = cfg["resolution"], cfg["seed"]
    mesh = objects.source_mesh(name, cfg["source_vertices"], seed, user_path)
    # The plane shares the head's map so S_lin = a S_head + (1 - a) S_plane keeps pixels aligned.
    mapped = objects.source_mesh("head", cfg["source_vertices"], seed) if name == "plane" else mesh
    gim = build_geometry_image(mapped.vertices, mapped.faces, n)
    if gim.flipped:
        raise RuntimeError(f"object {name}: harmonic map still has {gim.flipped} flipped triangles")
    rest = gim.resample(mesh.faces, mesh.vertices)
    names = sorted(mesh.blendshapes, key=BLENDSHAPES.index) if mesh.blendshapes else []
    deltas = (
        np.stack([gim.resample(mesh.faces, mesh.blendshapes[b]) for b in names])
        if names
        else np.zeros((0, n, n, 3))
    )
    error = reconstruction_error(mesh.vertices, mesh.faces, rest)
    kind = "user" if user_path else name
    io.save_npz(
        gim_out,
        rest=rest.astype(np.float32),
        deltas=deltas.astype(np.float32),
        blendshapes=np.array(names, dtype=str),
        uv=gim.uv,
        source_vertices=mesh.vertices,
        source_faces=mesh.faces,
        kind=np.array(kind),
    )
    stats = {
        "source_vertices": len(mesh.vertices),
        "source_faces": len(mesh.faces),
        "flipped_triangles": gim.flipped,
        "cotangent_weights": int(gim.method == "cotangent"),
        "recon_error_mean": error["mean"],
        "recon_error_max": error["max"],
        "seconds": time.perf_counter() - start,
    }
    log.info("%s: %s", name, stats)
    io.write_csv(stats_out, _tidy(name, "geometry image", "all", stats))


def _tidy(dataset: str, model: str, split: str, values: dict[str, float]) -> pd.DataFrame:
    return pd.DataFrame(
        [
            {
                "method": "prt",
                "dataset": dataset,
                "model": model,
                "split": split,
                "metric": k,
                "value": float(v),
            }
            for k, v in values.items()
        ]
    )


# ---------------------------------------------------------------- deformation sequences


#: Datasets of paper section 4.2.2, built on the head's geometry image.
EXPERIMENTS = ("head_linear", "head_excluded")


def make_sequence(name: str, gim_path: str, cfg: dict, out: str) -> None:
    """Deformation frames of every split (paper 3.2.2) and the section 4.2.2 experiments.

    Train and val are one smooth sequence (val frames a random subset, as the paper's
    450/50 split); test frames lie outside it: unseen blendshape combinations with weights
    up to 1.3 (head), a separately seeded simulation (cloth; training joins four), or
    unseen lattice motion (creature, user meshes). ``head_linear``: S_lin = a S_head +
    (1 - a) S_plane with a in [0, 1] for training, evenly spaced over ``linear_range`` for test.
    ``head_excluded``: the head without the ``excluded_expression`` blendshape in training;
    test shapes move from the mean training shape to that expression.
    """
    gim = io.load_npz(gim_path)
    kind = name if name in EXPERIMENTS else str(gim["kind"])
    rest = gim["rest"].astype(np.float64)
    n_train, n_val, n_test = (cfg["frames"][s] for s in SPLITS)
    if kind in EXPERIMENTS:
        n_train, n_test = min(n_train, cfg["experiment_train_frames"]), cfg["experiment_points"]
    seq_len = n_train + n_val
    rng = np.random.default_rng(stable_seed(cfg["seed"], name, "sequence"))
    test_rng = np.random.default_rng(stable_seed(cfg["seed"], name, "test"))
    builders = {
        "head": _head_sequences,
        "cloth": _cloth_sequences,
        "head_linear": _linear_sequences,
        "head_excluded": _excluded_sequences,
    }
    build = builders.get(kind, _lattice_sequences)
    seq_pos, seq_params, test_pos, test_params, extrapolated = build(
        gim, rest, seq_len, n_test, rng, test_rng, cfg
    )
    order = np.random.default_rng(stable_seed(cfg["seed"], name, "split")).permutation(seq_len)
    val_idx, train_idx = np.sort(order[:n_val]), np.sort(order[n_val:])
    io.save_npz(
        out,
        train_positions=seq_pos[train_idx].astype(np.float32),
        val_positions=seq_pos[val_idx].astype(np.float32),
        test_positions=test_pos.astype(np.float32),
        train_params=seq_params[train_idx].astype(np.float32),
        val_params=seq_params[val_idx].astype(np.float32),
        test_params=test_params.astype(np.float32),
        train_frame=train_idx,
        val_frame=val_idx,
        test_extrapolated=extrapolated,
        kind=np.array(kind),
    )


def _head_sequences(gim, rest, seq_len, n_test, rng, test_rng, cfg):
    deltas = gim["deltas"].astype(np.float64)
    weights = deform.smooth_walk(seq_len, len(deltas), rng)
    # Test: random combinations; every other frame has weights beyond the training
    # range [0, 1] (scaled by 1.1-1.3).
    test_w = test_rng.uniform(0.0, 1.0, (n_test, len(deltas)))
    extrapolated = np.zeros(n_test, bool)
    extrapolated[1::2] = True
    test_w[1::2] *= test_rng.uniform(1.1, 1.3, (len(test_w[1::2]), 1))
    seq_pos = deform.apply_blendshapes(rest, deltas, weights)
    return seq_pos, weights, deform.apply_blendshapes(rest, deltas, test_w), test_w, extrapolated


def _cloth_sequences(gim, rest, seq_len, n_test, rng, test_rng, cfg, simulations: int = 4):
    """Training: ``simulations`` runs with their own sphere position and wind, back to back
    (one run shows too few fold configurations to generalise); test: one more run."""
    lengths = [len(c) for c in np.array_split(np.arange(seq_len), simulations) if len(c)]
    seq_pos = np.concatenate([deform.simulate_cloth(rest, n, rng) for n in lengths])
    test_pos = deform.simulate_cloth(rest, n_test, test_rng)
    seq_params, test_params = _pca_params(seq_pos, test_pos)
    return seq_pos, seq_params, test_pos, test_params, np.zeros(n_test, bool)


def _lattice_sequences(gim, rest, seq_len, n_test, rng, test_rng, cfg):
    """Creature and user meshes: a moving free-form-deformation lattice."""
    lower, upper = rest.reshape(-1, 3).min(0), rest.reshape(-1, 3).max(0)
    pad = 0.05 * (upper - lower).max()
    lower, upper = lower - pad, upper + pad
    shape = (4, 4, 3)
    lattice = deform.ffd_lattice(lower, upper, shape)
    amplitude = 0.12 * float((upper - lower).max())
    flat = rest.reshape(-1, 3)

    def frames(disp):
        return np.stack([deform.ffd(flat, lower, upper, lattice + d) for d in disp]).reshape(
            -1, *rest.shape
        )

    seq_disp = deform.lattice_displacements(seq_len, shape, amplitude, rng)
    test_disp = deform.lattice_displacements(n_test, shape, amplitude, test_rng, period=37.0)
    return (
        frames(seq_disp),
        seq_disp.reshape(seq_len, -1),
        frames(test_disp),
        test_disp.reshape(n_test, -1),
        np.zeros(n_test, bool),
    )


def _linear_sequences(gim, rest, seq_len, n_test, rng, test_rng, cfg):
    """S_lin = a S_head + (1 - a) S_plane; the plane is the head's grid flattened (z = 0)."""
    plane = rest.copy()
    plane[..., 2] = 0.0
    a_train = rng.uniform(0.0, 1.0, seq_len)
    a_test = np.linspace(*cfg["linear_range"], n_test)

    def frames(a):
        return a[:, None, None, None] * rest + (1 - a[:, None, None, None]) * plane

    return (
        frames(a_train),
        a_train[:, None],
        frames(a_test),
        a_test[:, None],
        (a_test < 0) | (a_test > 1),
    )


def _excluded_sequences(gim, rest, seq_len, n_test, rng, test_rng, cfg):
    """Head walk without one expression; test moves from the mean shape to that expression."""
    deltas = gim["deltas"].astype(np.float64)
    names = [str(b) for b in gim["blendshapes"]]
    excluded = cfg["excluded_expression"]
    if excluded not in names:
        raise ValueError(f"prt.excluded_expression {excluded!r}: expected one of {names}")
    k = names.index(excluded)
    weights = deform.smooth_walk(seq_len, len(deltas), rng)
    weights[:, k] = 0.0
    target = np.zeros(len(deltas))
    target[k] = 1.0
    t = np.linspace(0.0, 1.0, n_test)[:, None]
    test_w = (1 - t) * weights.mean(0) + t * target
    seq_pos = deform.apply_blendshapes(rest, deltas, weights)
    return seq_pos, weights, deform.apply_blendshapes(rest, deltas, test_w), test_w, t[:, 0] > 0


def _pca_params(
    seq_pos: np.ndarray, test_pos: np.ndarray, count: int = 16
) -> tuple[np.ndarray, np.ndarray]:
    """Leading PCA coefficients of the position images (the shape parameters of a simulation)."""
    x = seq_pos.reshape(len(seq_pos), -1)
    mean = x.mean(0)
    _, _, vt = np.linalg.svd(x - mean, full_matrices=False)
    basis = vt[:count]
    return (x - mean) @ basis.T, (test_pos.reshape(len(test_pos), -1) - mean) @ basis.T


# ---------------------------------------------------------------- transfer ground truth


def channel_names(n_bands: int) -> dict[str, list[str]]:
    """EXR channel names: positions, normals, diffuse transfer, glossy radiance."""
    k = n_bands * n_bands
    return {
        "P": [f"P.{a}" for a in "xyz"],
        "N": [f"N.{a}" for a in "xyz"],
        "T": [f"T.{j:02d}" for j in range(k)],
        "G": [f"G.{c}.{j:02d}" for c in COLOURS for j in range(k)],
    }


def ray_offset(positions: np.ndarray, relative: float) -> float:
    """Origin offset in world units: ``relative`` times the rest shape's bounding-box diagonal."""
    p = positions.reshape(-1, 3)
    return relative * float(np.linalg.norm(p.max(0) - p.min(0)))


def compute_transfer(
    name: str,
    seq_path: str,
    light_csv: str,
    split: str,
    directions: int,
    cfg: dict,
    threads: int,
    out_dir: str,
    manifest: str,
) -> None:
    """Ray-trace diffuse and glossy transfer of every frame of a split, one EXR per frame."""
    seq = io.load_npz(seq_path)
    positions = seq[f"{split}_positions"]
    light = read_sh_light(light_csv)
    n_bands = cfg["n_bands"]
    faces = grid_faces(positions.shape[1])
    offset = ray_offset(positions[0], cfg["ray_offset"])
    names = channel_names(n_bands)
    Path(out_dir).mkdir(parents=True, exist_ok=True)
    rows = []
    for f in tqdm(range(len(positions)), desc=f"{name} {split}", mininterval=2.0):
        rng = np.random.default_rng(stable_seed(cfg["seed"], name, split, f, directions))
        start = time.perf_counter()
        sets = transfer.DirectionSets(cfg["direction_sets"], directions, n_bands, rng)
        normals, diffuse, glossy, rays = transfer.frame_transfer(
            positions[f], faces, sets, rng, offset, light[: n_bands**2], threads
        )
        seconds = time.perf_counter() - start
        channels = {}
        channels.update(zip(names["P"], np.moveaxis(positions[f], -1, 0), strict=True))
        channels.update(zip(names["N"], np.moveaxis(normals, -1, 0), strict=True))
        channels.update(
            zip(names["T"], np.moveaxis(diffuse.astype(np.float16), -1, 0), strict=True)
        )
        g = glossy.reshape(*glossy.shape[:2], -1).astype(np.float16)  # (n, n, 3 K), colour-major
        channels.update(zip(names["G"], np.moveaxis(g, -1, 0), strict=True))
        file = Path(out_dir) / f"frame_{f:04d}.exr"
        io.write_exr(file, channels)
        rows.append(
            {
                "frame": f,
                "split": split,
                "file": file.name,
                "directions": directions,
                "rays": rays,
                "seconds": seconds,
                "rays_per_s": rays / seconds,
                "extrapolated": bool(seq["test_extrapolated"][f]) if split == "test" else False,
            }
        )
    io.write_csv(manifest, pd.DataFrame(rows))


def read_frame(path: str | Path, n_bands: int) -> dict[str, np.ndarray]:
    """One frame EXR as arrays: P, N ``(n, n, 3)``, T ``(n, n, K)``, G ``(n, n, 3, K)`` float32."""
    names = channel_names(n_bands)
    ch = io.read_exr(path, [c for group in names.values() for c in group])
    stack = {
        key: np.stack([ch[c].astype(np.float32) for c in cols], -1) for key, cols in names.items()
    }
    n = stack["P"].shape[0]
    stack["G"] = stack["G"].reshape(n, n, 3, n_bands * n_bands)
    return stack


# ---------------------------------------------------------------- noise floor


def radiance_images(transfer_maps: np.ndarray, light: np.ndarray) -> np.ndarray:
    """Relit diffuse radiance ``(F, 3, n, n)`` of transfer maps ``(F, n, n, K)`` (albedo 1)."""
    rgb = transfer.relight_diffuse(transfer_maps, light)
    return np.moveaxis(rgb, -1, 1)


def noise_floor(
    name: str, seq_path: str, reference_dir: str, light_csv: str, cfg: dict, threads: int, out: str
) -> None:
    """SSIM and L1 of training-quality ground truth against an independent sample and the reference.

    On the first ``noise_floor_frames`` test frames, two independently seeded ground truths
    with ``directions`` samples are relit (diffuse, albedo 1, the stage's light) in
    geometry-image space, divided by the reference radiance's maximum so that images lie in
    [0, 1], and compared with each other and with the clean reference.
    """
    import torch

    from neurender import metrics

    seq = io.load_npz(seq_path)
    n_bands, directions = cfg["n_bands"], cfg["directions"]
    light = read_sh_light(light_csv)[: n_bands**2]
    frames = range(min(cfg["noise_floor_frames"], len(seq["test_positions"])))
    faces = grid_faces(seq["test_positions"].shape[1])
    offset = ray_offset(seq["test_positions"][0], cfg["ray_offset"])
    rows = []
    for f in tqdm(frames, desc=f"{name} noise floor"):
        ref = read_frame(Path(reference_dir) / f"frame_{f:04d}.exr", n_bands)
        samples = []
        for trial in ("a", "b"):
            rng = np.random.default_rng(stable_seed(cfg["seed"], name, "noise", f, trial))
            sets = transfer.DirectionSets(cfg["direction_sets"], directions, n_bands, rng)
            _, diffuse, glossy, _ = transfer.frame_transfer(
                seq["test_positions"][f], faces, sets, rng, offset, light, threads
            )
            samples.append((diffuse, glossy))
        imgs = radiance_images(np.stack([samples[0][0], samples[1][0], ref["T"]]), light)
        scale = imgs[2].max()
        a, b, r = (torch.from_numpy(np.ascontiguousarray(i[None] / scale)).double() for i in imgs)
        values = {
            "ssim_sample_vs_sample": metrics.ssim(a, b),
            "ssim_sample_vs_reference": metrics.ssim(a, r),
            "l1_sample_vs_sample": metrics.l1(a, b),
            "l1_sample_vs_reference": metrics.l1(a, r),
            "l1_transfer_vs_reference": float(np.abs(samples[0][0] - ref["T"]).mean()),
            "l1_glossy_vs_reference": float(np.abs(samples[0][1] - ref["G"]).mean()),
        }
        for metric, value in values.items():
            rows.append(
                {
                    "method": "prt",
                    "dataset": name,
                    "model": f"ground truth {directions} dirs",
                    "split": "test",
                    "frame": f,
                    "metric": metric,
                    "value": float(value),
                }
            )
    io.write_csv(out, pd.DataFrame(rows))


# ---------------------------------------------------------------- summary and figure


def summarise(
    gim_csvs: list[str], manifests: list[str], noise_csvs: list[str], data_out: str, noise_out: str
) -> None:
    """Collect per-object statistics into ``data.csv`` and the noise floor into one table."""
    frames = [io.read_csv(p) for p in gim_csvs]
    for path in manifests:
        m = io.read_csv(path, ["split", "rays", "seconds"])
        dataset = Path(path).parent.name
        stats = {
            "frames": len(m),
            "directions": m["directions"].iloc[0],
            "seconds_per_frame": m["seconds"].mean(),
            "rays_per_s": m["rays"].sum() / m["seconds"].sum(),
        }
        frames.append(_tidy(dataset, "ray-traced ground truth", m["split"].iloc[0], stats))
    io.write_csv(data_out, pd.concat(frames, ignore_index=True))
    noise = pd.concat([io.read_csv(p) for p in noise_csvs], ignore_index=True)
    io.write_csv(noise_out, noise.drop(columns="frame"))


def frames_figure(
    name: str, test_dir: str, light_csv: str, n_bands: int, out: str, count: int = 3
) -> None:
    """Position, normal, diffuse-transfer and relit-radiance images of a few test frames."""
    files = sorted(Path(test_dir).glob("frame_*.exr"))[:count]
    if not files:
        raise FileNotFoundError(f"no frame_*.exr files in {test_dir}")
    light = read_sh_light(light_csv)[: n_bands**2]
    fig, axes = plt.subplots(len(files), 4, figsize=(10, 2.6 * len(files)), squeeze=False)
    for row, file in zip(axes, files, strict=True):
        fr = read_frame(file, n_bands)
        p = fr["P"]
        pn = (p - p.min((0, 1))) / np.maximum(np.ptp(p, (0, 1)), 1e-9)
        radiance = transfer.relight_diffuse(fr["T"], light)
        panels = [
            (pn, "P (normalised)"),
            ((fr["N"] + 1) / 2, "N (n+1)/2"),
            (fr["T"][..., 0] / max(fr["T"][..., 0].max(), 1e-9), "T.00 (ambient occlusion)"),
            (
                np.clip(radiance / np.percentile(radiance, 99.5), 0, 1) ** (1 / 2.2),
                "relit, diffuse",
            ),
        ]
        for ax, (img, title) in zip(row, panels, strict=True):
            ax.imshow(np.clip(img, 0, 1), cmap="gray" if img.ndim == 2 else None, origin="lower")
            ax.set_title(f"{file.stem}: {title}", fontsize=7)
            ax.axis("off")
    fig.suptitle(f"DeepPRT data: {name}, test frames (geometry-image space)")
    fig.tight_layout()
    save_figure(fig, out)


def probes_figure(exrs: list[str], sh_csvs: list[str], out: str) -> None:
    """Each probe, its SH reconstruction and the halfway blend of the first two (paper Fig. 2)."""

    def tonemap(img: np.ndarray) -> np.ndarray:
        return np.clip(img / (1.0 + img), 0, 1) ** (1 / 2.2)

    images = [lights.load_probe(p) for p in exrs]
    coeffs = [read_sh_light(p) for p in sh_csvs]
    panels = []
    for path, img, c in zip(exrs, images, coeffs, strict=True):
        h = img.shape[0]
        panels.append((img, f"{Path(path).stem}"))
        panels.append(
            (np.clip(sh.reconstruct_latlong(c, h, 2 * h), 0, None), f"{Path(path).stem}, SH")
        )
    if len(coeffs) >= 2:
        h = images[0].shape[0]
        mid = np.clip(sh.reconstruct_latlong(0.5 * (coeffs[0] + coeffs[1]), h, 2 * h), 0, None)
        panels.append((mid, "halfway interpolation, SH"))
    fig, axes = plt.subplots(1, len(panels), figsize=(3.2 * len(panels), 2.0), squeeze=False)
    for ax, (img, title) in zip(axes[0], panels, strict=True):
        ax.imshow(tonemap(img))
        ax.set_title(title, fontsize=8)
        ax.axis("off")
    fig.tight_layout()
    save_figure(fig, out)
