"""Figures of DeepPRT: data, predictions (Fig. 7), light probes (Fig. 2), training curves,
the equal-quality comparison, the section 4.2.2 experiments (Fig. 6) and relighting.

Radiance images are shown divided by their ground truth's maximum with gamma 2.2
(:func:`neurender.display.gamma`); HDR probes with Reinhard and gamma
(:func:`neurender.display.tonemap`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from neurender import equal_quality as shared
from neurender import io, lights, sh
from neurender.display import gamma, tonemap
from neurender.plots import plt, save_figure
from neurender.prt import MATERIALS, transfer
from neurender.prt import equal_quality as eq
from neurender.prt.frames import read_frame, read_sh_light


def frames_figure(
    name: str, test_dir: str, light_csv: str, n_bands: int, out: str, count: int = 3
) -> None:
    """Position, normal, diffuse-transfer and relit-radiance images of a few test frames."""
    files = sorted(Path(test_dir).glob("frame_*.exr"))[:count]
    if not files:
        raise FileNotFoundError(f"no frame_*.exr files in {test_dir}")
    light = read_sh_light(light_csv, n_bands)
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
                gamma(radiance / np.percentile(radiance, 99.5)),
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


def prediction_figure(name: str, panels: dict | None, out: str) -> None:
    """GT | prediction | SSIM map | L1 map per model and material (paper Fig. 7)."""
    if not panels:
        raise ValueError(f"{name}: no test frame to draw")
    keys = [k for k in panels if not k[0].startswith("ground truth")] + [
        k for k in panels if k[0].startswith("ground truth")
    ]
    fig, axes = plt.subplots(len(keys), 4, figsize=(9, 2.4 * len(keys)), squeeze=False)
    for row, key in zip(axes, keys, strict=True):
        gt, img, scores, mask = panels[key]
        scale = gt.max()
        show = [
            np.moveaxis(gamma(gt / scale), 0, -1),
            np.moveaxis(gamma(img / scale), 0, -1),
        ]
        row[0].imshow(show[0])
        row[0].set_title(f"{key[1]}: ground truth", fontsize=7)
        row[1].imshow(show[1])
        row[1].set_title(f"{key[0]} (SSIM {scores['ssim']:.3f})", fontsize=7)
        row[2].imshow(scores["ssim_map"], vmin=0.5, vmax=1, cmap="viridis")
        row[2].set_title("SSIM map", fontsize=7)
        im = row[3].imshow(scores["l1_map"], vmin=0, vmax=0.1, cmap="magma")
        row[3].set_title("L1 map", fontsize=7)
        for ax in row:
            ax.axis("off")
        fig.colorbar(im, ax=row[3], fraction=0.046)
    fig.suptitle(
        f"DeepPRT: {name}, a test frame (the first extrapolated one if any) vs its clean reference"
    )
    fig.tight_layout()
    save_figure(fig, out)


def loss_figure(loss_csvs: dict, out: str) -> None:
    """Training and validation L1 per object, variant and material (``loss_csvs`` keyed
    ``(object, model name, material)``): a panel per variant and material; the variants'
    losses are of different targets (normalised transfer, normalised shadowing term)."""
    models = list(dict.fromkeys(model for _, model, _ in loss_csvs))
    fig, axes = plt.subplots(
        len(models), len(MATERIALS), figsize=(9, 3.2 * len(models)), squeeze=False
    )
    for (obj, model, material), path in sorted(loss_csvs.items()):
        log_table = io.read_csv(path, ["epoch", "split", "metric", "value"])
        ax = axes[models.index(model), MATERIALS.index(material)]
        for split, style in (("train", "--"), ("val", "-")):
            sel = log_table[(log_table.split == split) & (log_table.metric == "loss")]
            ax.semilogy(sel.epoch, sel.value, style, label=f"{obj} {split}")
        ax.set_title(f"{model} {material}: L1 (normalised targets)", fontsize=9)
        ax.set_xlabel("epoch")
    axes[0, 0].legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, out)


def _equal_quality_panel(ax, equal: pd.DataFrame, model: str):
    """One variant's panel of :func:`equal_quality_figure`; returns ``(lowest SSIM
    target, every time drawn in ms)``."""
    lowest, span = 1.0, []
    for i, (name, rows) in enumerate(equal.groupby("dataset", sort=True)):
        traced = rows[rows.model == eq.RAY_TRACED].pivot_table(
            index="setting", columns="metric", values="value", sort=False
        )
        traced = traced.sort_values("ms_per_frame")
        mine = rows[rows.model == model]
        if mine.empty:
            continue
        value = mine.set_index("metric")["value"]
        target = value["ssim_diffuse"]
        lowest = min(lowest, target)
        colour = f"C{i}"
        ax.plot(
            traced["ms_per_frame"],
            traced["ssim_diffuse"],
            "o-",
            ms=3,
            color=colour,
            label=f"{name}: ray traced",
        )
        for setting, r in traced.iterrows():
            ax.annotate(
                setting.split()[0],
                (r["ms_per_frame"], r["ssim_diffuse"]),
                fontsize=6,
                color=colour,
                xytext=(3, -9 - 7 * i),
                textcoords="offset points",
            )
        stated = shared.stated(value[shared.SPEEDUP], mine["bound"].iloc[0])
        ax.plot(
            [value["ms_per_frame"]],
            [target],
            "*",
            ms=12,
            color=colour,
            label=f"{name}: network, {stated} at equal SSIM",
        )
        span += [*traced["ms_per_frame"], value["ms_per_frame"]]
        if "inference_ms_per_frame_pytorch" in value:  # the same network in PyTorch
            ax.plot(
                [value["inference_ms_per_frame_pytorch"]],
                [target],
                "*",
                ms=10,
                mfc="none",
                color=colour,
                label="hollow stars: the same network in PyTorch" if i == 0 else None,
            )
            span.append(value["inference_ms_per_frame_pytorch"])
    return lowest, span


def equal_quality_figure(equal: pd.DataFrame, models: list[str], out: str) -> None:
    """SSIM against the clean reference vs milliseconds per frame, a panel per variant
    (``models``: their names), from the equal-quality table ``equal``
    (:func:`neurender.prt.equal_quality.table`, every object's): the ray-traced estimates
    of every direction count (a curve per object, labelled with its count) and the
    variant's network (a star; a hollow star: the same network run by PyTorch, where
    timed), measured on the first test frames; the equal-quality ratio is the horizontal
    gap."""
    fig, axes = plt.subplots(1, len(models), figsize=(6.5 * len(models), 3.8), squeeze=False)
    ticks = (0.5, 1, 2, 5, 10, 20, 50, 100, 200, 500, 1000, 2000, 5000)
    for ax, model in zip(axes[0], models, strict=True):
        lowest, span = _equal_quality_panel(ax, equal, model)
        ax.set_xscale("log")
        ax.xaxis.set_major_formatter(plt.ScalarFormatter())
        ax.xaxis.set_minor_formatter(plt.NullFormatter())
        ax.set_xticks([t for t in ticks if min(span) / 1.5 <= t <= max(span) * 1.5])
        ax.set_ylim(max(0.0, lowest - 0.1), 1.0)
        ax.set_xlabel("milliseconds per frame (same machine and threads)")
        ax.set_ylabel("diffuse SSIM vs clean reference")
        ax.set_title(f"{model} vs ray-traced transfer (labels: directions)", fontsize=9)
        ax.legend(fontsize=7, loc="lower left")
    fig.tight_layout()
    save_figure(fig, out)


def experiment_figure(name: str, table: pd.DataFrame, label: str, out: str) -> None:
    """Paper Fig. 6: diffuse L2-RGB of every model of ``table`` (each DeepPRT variant
    and MoMoPRT) along a test path ``x``."""
    fig, ax = plt.subplots(figsize=(5, 3.2))
    sel = table[table.metric == "l2rgb_diffuse"]
    for i, model in enumerate(dict.fromkeys(sel.model)):
        rows = sel[sel.model == model]
        style = "s--" if model == "MoMoPRT" else "o^v"[i % 3] + "-"
        ax.semilogy(rows.x, rows.value, style, label=model)
    if name == "head_linear":
        ax.axvspan(0, 1, color="0.9", label="training range")
    ax.set_xlabel(label)
    ax.set_ylabel("mean L2-RGB (diffuse)")
    ax.set_title(f"DeepPRT paper Fig. 6: {name}")
    ax.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, out)


def unseen_figure(name: str, table: pd.DataFrame, out: str) -> None:
    """Paper Fig. 6 generalised: relative L1 of radiance against deformation strength,
    one panel per unseen family (columns) and material (rows), one line per model
    (:mod:`neurender.prt.unseen_scores`)."""
    families = list(dict.fromkeys(table.family))
    models = list(dict.fromkeys(table.model))
    fig, axes = plt.subplots(
        len(MATERIALS),
        len(families),
        figsize=(2.6 * len(families), 2.4 * len(MATERIALS)),
        squeeze=False,
        sharex=True,
    )
    for row, material in enumerate(MATERIALS):
        for col, family in enumerate(families):
            ax = axes[row, col]
            sel = table[(table.family == family) & (table.metric == f"rel_l1_radiance_{material}")]
            for i, model in enumerate(models):  # a model's colour and marker in every panel
                line = sel[sel.model == model].sort_values("strength")
                if len(line):
                    style = {"color": f"C{i}", "marker": "os^vDx*"[i % 7], "ms": 3}
                    ax.semilogy(line.strength, line.value, label=model, **style)
            ax.set_title(f"{family} ({material})", fontsize=8)
            ax.tick_params(labelsize=7)
            if row == len(MATERIALS) - 1:
                ax.set_xlabel("strength", fontsize=8)
            if col == 0:
                ax.set_ylabel("rel. L1 of radiance", fontsize=8)
    handles = {}
    for ax in axes.flat:  # MoMoPRT is in some panels only: one legend for the figure
        handles.update(zip(*reversed(ax.get_legend_handles_labels()), strict=True))
    fig.legend(handles.values(), handles.keys(), loc="upper right", fontsize=7, ncol=len(handles))
    title = f"DeepPRT {name}: unseen deformations of the mean shape"
    fig.suptitle(title, x=0.01, ha="left", fontsize=9)
    fig.tight_layout(rect=(0, 0, 1, 0.93))
    save_figure(fig, out)


def relight_figure(name: str, blends: list[tuple[float, np.ndarray, np.ndarray, float]], out: str):
    """Paper Fig. 2: ground truth over DeepPRT for each ``(blend weight, ground-truth image
    (3, H, W), prediction (3, H, W), SSIM)`` of one test frame under blended probes."""
    steps = len(blends)
    fig, axes = plt.subplots(2, steps, figsize=(2.2 * steps, 4.6), squeeze=False)
    for i, (w, gt, img, ssim) in enumerate(blends):
        scale = gt.max()
        for r, im in enumerate((gt, img)):
            axes[r, i].imshow(np.moveaxis(gamma(im / scale), 0, -1))
            axes[r, i].axis("off")
        axes[0, i].set_title(f"blend {w:.2f}: ground truth", fontsize=7)
        axes[1, i].set_title(f"DeepPRT, SSIM {ssim:.3f}", fontsize=7)
    fig.suptitle(f"DeepPRT paper Fig. 2: {name} test frame 0 under a blend of two light probes")
    fig.tight_layout()
    save_figure(fig, out)


def meshes_figure(
    name: str, rest: np.ndarray, train: np.ndarray, test: np.ndarray, out: str, count: int = 3
) -> None:
    """PyVista figure of an object's geometry image (its rest grid mesh ``(n, n, 3)`` with
    its grid lines, large enough that every one of a 64 x 64 grid's cells shows) and of
    ``count`` training frames (first, evenly spaced, last) and the first test frame
    (``(F, n, n, 3)`` each), coloured by each grid point's distance from its rest position
    (world units)."""
    from neurender.mesh_figures import Panel, render_panels

    n = rest.shape[0]
    picks = np.unique(np.linspace(0, len(train) - 1, count).round().astype(int))
    frames = [(f"train frame {k}", train[k]) for k in picks] + [("test frame 0", test[0])]
    distances = [np.linalg.norm(p - rest, axis=-1) for _, p in frames]
    top = max(float(max(d.max() for d in distances)), 1e-9)
    panels = [Panel(rest, title=f"{name}: geometry image {n} x {n} (rest)", edges=True)]
    panels += [
        Panel(
            p,
            title=title,
            scalars=d,
            clim=(0.0, top),
            scalar_title="distance from rest" if k == len(frames) - 1 else None,
        )
        for k, ((title, p), d) in enumerate(zip(frames, distances, strict=True))
    ]
    render_panels(panels, out, (2, 4), (1100, 550), groups=[(slice(0, 2), slice(0, 2))])
