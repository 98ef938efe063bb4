"""Quantitative evaluation of image-space metaballs (the thesis shows only pictures).

Buffers are ``(7, W, W)`` in [0, 1]: colour (3), depth (1, background 1), encoded normal
(3, background 0). Silhouettes: depth below ``DEPTH_FOREGROUND`` of the range (networks
predict background depth near 0.97, not 1), or, as thesis 7.1, a non-black normal buffer
(channel sum above ``NORMAL_FOREGROUND``; a unit normal's encoding always sums to more).
Normal errors are angles between decoded unit normals inside the true silhouette; depth
errors are in world units inside the true silhouette.

No-learning baselines: "isolated spheres" (every ball a sphere of radius ``r``: exactly what
a circle of the input encodes, without the blend) and "inflated spheres" (radius grown by
the other balls' field, :func:`neurender.metaballs.inputs.inflated_radii`: the prior our
residual model starts from).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import torch
from tqdm import tqdm

from neurender import metrics
from neurender.metaballs import inputs, scenes

DEPTH_FOREGROUND = 0.95
NORMAL_FOREGROUND = 0.3
BUFFERS = {"colour": slice(0, 3), "depth": slice(3, 4), "normal": slice(4, 7)}


def silhouette_depth(buffers: torch.Tensor) -> torch.Tensor:
    """``(W, W)`` bool foreground of a ``(7, W, W)`` stack by depth."""
    return buffers[3] < DEPTH_FOREGROUND


def silhouette_normal(buffers: torch.Tensor) -> torch.Tensor:
    """``(W, W)`` bool foreground by a non-black normal buffer (thesis 7.1)."""
    return buffers[4:7].sum(0) > NORMAL_FOREGROUND


def iou(a: torch.Tensor, b: torch.Tensor) -> float:
    union = (a | b).sum()
    return float((a & b).sum() / union) if union else 1.0


def normal_angles(pred: torch.Tensor, gt: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Angles in degrees ``(M,)`` between decoded normals of two stacks inside ``mask``."""
    a = pred[4:7][:, mask] * 2 - 1
    b = gt[4:7][:, mask] * 2 - 1
    cos = (a * b).sum(0) / (a.norm(dim=0) * b.norm(dim=0)).clamp(min=1e-8)
    return torch.rad2deg(torch.acos(cos.clamp(-1, 1)))


def example_metrics(pred: torch.Tensor, gt: torch.Tensor) -> dict[str, float]:
    """All metrics of one predicted ``(7, W, W)`` stack against the ray-marched one."""
    out = {}
    for name, sl in BUFFERS.items():
        a, b = pred[None, sl].double(), gt[None, sl].double()
        out[f"l1_{name}"] = float(metrics.l1(a, b))
        out[f"ssim_{name}"] = float(metrics.ssim(a, b))
    true_fg = silhouette_depth(gt)
    out["iou_depth"] = iou(silhouette_depth(pred), true_fg)
    out["iou_normal"] = iou(silhouette_normal(pred), silhouette_normal(gt))
    if true_fg.any():
        span = scenes.MAX_DEPTH - scenes.MIN_DEPTH
        out["depth_error_world"] = float((pred[3][true_fg] - gt[3][true_fg]).abs().mean() * span)
        angles = normal_angles(pred, gt, true_fg)
        out["normal_error_mean_deg"] = float(angles.mean())
        out["normal_error_median_deg"] = float(angles.median())
    return out


def overlap_image(pred: torch.Tensor, gt: torch.Tensor) -> np.ndarray:
    """Thesis Fig. 7.2 ``(W, W, 3)``: true silhouette red, predicted green, agreement yellow."""
    img = np.zeros((*gt.shape[1:], 3), np.float32)
    img[..., 0] = silhouette_normal(gt).numpy()
    img[..., 1] = silhouette_normal(pred).numpy()
    return img


def binned(frame: pd.DataFrame, column: str, edges: list[float]) -> pd.DataFrame:
    """Mean of each metric per model in bins of ``column`` (e.g. balls, depth separation)."""
    bins = pd.cut(frame[column], edges, include_lowest=True)
    return (
        frame.assign(bin=bins.astype(str))
        .groupby(["model", "bin", "metric"], observed=True, as_index=False)["value"]
        .mean()
    )


def baselines(scene: scenes.Scene, width: int) -> dict[str, torch.Tensor]:
    """The no-learning baselines' ``(7, W, W)`` stacks of a scene."""
    return {
        "isolated spheres": inputs.draw_spheres(scene, width).stack(),
        "inflated spheres": inputs.inflated_spheres(scene, width).stack(),
    }


def evaluate_models(
    test_dir: str,
    test_manifest: str,
    test_balls: str,
    checkpoints: dict[str, str],
    cfg: dict,
    threads: int,
    metrics_out: str,
    examples_out: str,
    by_scene_out: str,
    figure_out: str,
    scene_figure_out: str,
) -> None:
    """Score every model and the sphere baselines on the held-out scenes."""
    from neurender import io
    from neurender.metaballs import ab
    from neurender.metaballs.data import read_scenes
    from neurender.metaballs.model import MetaballRenderer

    manifest = io.read_csv(test_manifest, ["example", "file", "balls", "min_depth_separation"])
    scene_of = read_scenes(test_balls)
    renderers = {
        label: MetaballRenderer(path, cfg["device"], threads) for label, path in checkpoints.items()
    }
    rows, visual = [], None
    for _, ex in tqdm(manifest.sort_values("example").iterrows(), total=len(manifest)):
        parts = ab.read_ab(Path(test_dir) / ex["file"])
        gt = torch.cat([parts["colour"], parts["depth"], parts["normal"]])
        scene = scene_of[int(ex["example"])]
        preds = {
            label: r(r.inputs(scene, parts["inputs"])[None])[0] for label, r in renderers.items()
        }
        preds.update(baselines(scene, cfg["width"]))
        for model, pred in preds.items():
            for metric, value in example_metrics(pred, gt).items():
                rows.append(
                    {
                        "method": "metaballs",
                        "dataset": "test scenes",
                        "model": model,
                        "split": "test",
                        "example": int(ex["example"]),
                        "balls": int(ex["balls"]),
                        "min_depth_separation": ex["min_depth_separation"],
                        "metric": metric,
                        "value": value,
                    }
                )
        if visual is None or ex["balls"] > visual[0]:  # show the busiest scene
            visual = (int(ex["balls"]), parts["inputs"], gt, preds)
    frame = pd.DataFrame(rows)
    io.write_csv(examples_out, frame)
    keys = ["method", "dataset", "model", "split", "metric"]
    io.write_csv(metrics_out, frame.groupby(keys, as_index=False, sort=False)["value"].mean())
    hi = int(frame["balls"].max())
    by_balls = binned(frame, "balls", [0, 5, 10, 15, max(hi, 16)]).assign(by="balls")
    by_gap = binned(
        frame.dropna(subset=["min_depth_separation"]), "min_depth_separation", [0, 0.5, 1, 2, 5, 20]
    )
    by_scene = pd.concat([by_balls, by_gap.assign(by="min_depth_separation")], ignore_index=True)
    io.write_csv(by_scene_out, by_scene)
    _accuracy_figure(by_scene, scene_figure_out)
    _visual_figure(visual[1:], figure_out)


def _accuracy_figure(by_scene: pd.DataFrame, out: str) -> None:
    from neurender.plots import plt, save_figure

    fig, axes = plt.subplots(2, 2, figsize=(9, 6))
    for col, by in enumerate(("balls", "min_depth_separation")):
        for row, metric in enumerate(("iou_depth", "normal_error_mean_deg")):
            ax = axes[row, col]
            sel = by_scene[(by_scene.by == by) & (by_scene.metric == metric)]
            for model, part in sel.groupby("model", sort=False):
                ax.plot(part["bin"], part["value"], "o-", label=model)
            ax.set_xlabel(
                "number of balls"
                if by == "balls"
                else "depth gap of overlapping balls (world units)"
            )
            ax.set_ylabel(metric)
            ax.tick_params(axis="x", labelsize=7)
    axes[0, 0].legend(fontsize=7)
    fig.suptitle("Metaballs: accuracy against scene complexity (held-out scenes)")
    fig.tight_layout()
    save_figure(fig, out)


def _visual_figure(visual, out: str) -> None:
    """Thesis Fig. 7.2: normals, silhouette overlap and enhanced differences per model."""
    from neurender.plots import plt, save_figure

    inputs, gt, preds = visual
    fig, axes = plt.subplots(len(preds), 5, figsize=(11, 2.4 * len(preds)), squeeze=False)
    for row, (model, pred) in zip(axes, preds.items(), strict=True):
        panels = [
            (inputs[:3].permute(1, 2, 0), "input circles"),
            (gt[4:7].permute(1, 2, 0), "ray-marched normals"),
            (pred[4:7].permute(1, 2, 0), f"{model}: normals"),
            (overlap_image(pred, gt), "overlap: red truth, green predicted"),
            (((pred[:3] - gt[:3]).abs() * 4).clamp(0, 1).permute(1, 2, 0), "colour difference x4"),
        ]
        for ax, (img, title) in zip(row, panels, strict=True):
            ax.imshow(np.asarray(img))
            ax.set_title(title, fontsize=7)
            ax.axis("off")
    fig.tight_layout()
    save_figure(fig, out)


def target_rows(metrics_csv: str, timing_csv: str, paper_scale: bool, out: str) -> None:
    """The issue's targets, each stated as met or missed."""
    from neurender import io

    m = io.read_csv(metrics_csv, ["model", "metric", "value"])
    t = io.read_csv(timing_csv, ["model", "metric", "value"])

    def get(model: str, metric: str) -> float:
        sel = m[(m.model == model) & (m.metric == metric)]
        return float(sel.value.iloc[0]) if len(sel) else math.nan

    iou_target, angle_target = (0.95, 8.0) if paper_scale else (0.90, 15.0)
    lower_better = ("l1_", "depth_error", "normal_error")
    rows = []
    for model in [x for x in m.model.unique() if not x.endswith(" spheres")]:
        iou_v, angle = get(model, "iou_depth"), get(model, "normal_error_mean_deg")
        rows.append(
            {
                "check": f"{model}: silhouette IoU (depth) >= {iou_target}",
                "measured": iou_v,
                "met": iou_v >= iou_target,
            }
        )
        rows.append(
            {
                "check": f"{model}: mean normal error <= {angle_target} deg",
                "measured": angle,
                "met": angle <= angle_target,
            }
        )
        for metric in sorted(set(m.metric)):
            ours, base = get(model, metric), get("isolated spheres", metric)
            better = ours < base if metric.startswith(lower_better) else ours > base
            rows.append(
                {
                    "check": f"{model}: better than isolated spheres on {metric} ({base:.4g})",
                    "measured": ours,
                    "met": bool(better),
                }
            )
    for speed in t[t.metric.str.startswith("speedup_at_")].itertuples():
        rows.append(
            {
                "check": f"{speed.model}: frame >= 10x faster than ray marching ({speed.metric})",
                "measured": float(speed.value),
                "met": float(speed.value) >= 10,
            }
        )
    io.write_csv(out, pd.DataFrame(rows))
