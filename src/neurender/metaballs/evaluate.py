"""Quantitative evaluation of image-space metaballs on held-out scenes (the thesis shows
only pictures).

Predictions and truths are G-buffer stacks ``(7, W, W)`` in [0, 1]
(:mod:`neurender.metaballs.gbuffers`). Per buffer: L1 and SSIM. Silhouette IoU by depth and
by the normal buffer. Normal errors are angles between decoded unit normals inside the true
silhouette (by depth); depth errors are in world units inside it. A frame whose reference
shows no surface (an empty true silhouette by depth) is not scored: every metric would call
an empty prediction perfect. Its row ``empty_frame`` is 1 (0 on every scored frame) and the
means leave it out, counting such frames per model as ``empty_frames``.

No-learning baselines: "isolated spheres" (every ball a sphere of radius ``r``: exactly what
a circle of the input encodes, without the blend), "inflated spheres" (radius grown by
the other balls' field, :func:`neurender.metaballs.inputs.inflated_radii`: the prior our
residual model starts from) and "refined spheres" (those impostors refined on the field,
:mod:`neurender.metaballs.refined`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from pathlib import Path

import pandas as pd
import torch
from tqdm import tqdm

from neurender import metrics
from neurender.metaball import Scene
from neurender.metaballs import (
    EMPTY_FRAME,
    EMPTY_FRAMES,
    REFINED_BASELINE,
    ab,
    gbuffers,
    inputs,
    scenes,
)
from neurender.metaballs.refined import refined_spheres
from neurender.metaballs.renderer import MetaballRenderer
from neurender.tables import tidy_rows
from neurender.train import epochs_trained

#: Bin edges of the accuracy-by-scene table: number of balls (the last edge grows to the
#: most balls seen) and depth gap of overlapping balls (world units).
BALL_EDGES = [0, 5, 10, 15, 16]
GAP_EDGES = [0, 0.5, 1, 2, 5, 20]
#: The ``dataset`` of the held-out scenes' rows.
TEST_DATASET = "test scenes"


def iou(a: torch.Tensor, b: torch.Tensor) -> float:
    """Intersection over union of two bool masks; NaN when both are empty (nothing to
    overlap: an empty prediction of an empty reference is not a perfect one)."""
    union = (a | b).sum()
    return float((a & b).sum() / union) if union else math.nan


def normal_angles(pred: torch.Tensor, gt: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Angles in degrees ``(M,)`` between decoded normals of two stacks inside ``mask``."""
    a = gbuffers.decoded_normals(pred)[:, mask]
    b = gbuffers.decoded_normals(gt)[:, mask]
    cos = (a * b).sum(0) / (a.norm(dim=0) * b.norm(dim=0)).clamp(min=1e-8)
    return torch.rad2deg(torch.acos(cos.clamp(-1, 1)))


def example_metrics(pred: torch.Tensor, gt: torch.Tensor) -> dict[str, float]:
    """All metrics of one predicted stack against the ray-marched one, then
    :data:`~neurender.metaballs.EMPTY_FRAME` 0; for a reference without a surface pixel
    (by depth) only ``EMPTY_FRAME`` 1."""
    true_fg = gbuffers.silhouette_depth(gt)
    if not true_fg.any():
        return {EMPTY_FRAME: 1.0}
    out = {}
    for name, channels in gbuffers.LAYOUT.items():
        a, b = pred[None, channels].double(), gt[None, channels].double()
        out[f"l1_{name}"] = float(metrics.l1(a, b))
        out[f"ssim_{name}"] = float(metrics.ssim(a, b))
    out["iou_depth"] = iou(gbuffers.silhouette_depth(pred), true_fg)
    out["iou_normal"] = iou(gbuffers.silhouette_normal(pred), gbuffers.silhouette_normal(gt))
    span = scenes.MAX_DEPTH - scenes.MIN_DEPTH
    depth_pred, depth_gt = pred[gbuffers.DEPTH][0], gt[gbuffers.DEPTH][0]
    out["depth_error_world"] = float((depth_pred[true_fg] - depth_gt[true_fg]).abs().mean() * span)
    angles = normal_angles(pred, gt, true_fg)
    out["normal_error_mean_deg"] = float(angles.mean())
    out["normal_error_median_deg"] = float(angles.median())
    out[EMPTY_FRAME] = 0.0
    return out


def baselines(scene: Scene, width: int) -> dict[str, torch.Tensor]:
    """The no-learning baselines' stacks of a scene."""
    return {
        "isolated spheres": inputs.draw_spheres(scene, width).stack(),
        "inflated spheres": inputs.inflated_spheres(scene, width).stack(),
        REFINED_BASELINE: refined_spheres(scene, width).stack(),
    }


@dataclasses.dataclass
class Showcase:
    """One held-out example for the comparison figure: its circles ``(4, W, W)``, the
    ray-marched stack and every model's prediction, all in [0, 1]."""

    balls: int
    circles: torch.Tensor
    truth: torch.Tensor
    predictions: dict[str, torch.Tensor]


def score_test_set(
    test_dir: str | Path,
    manifest: pd.DataFrame,
    scene_of: Mapping[int, Scene],
    renderers: Mapping[str, MetaballRenderer],
    width: int,
) -> tuple[pd.DataFrame, Showcase]:
    """Every model's and baseline's metrics on every held-out example, as tidy rows keyed
    by ``example, balls, min_depth_separation``; and the busiest scene to show.

    Args:
        manifest: the test split's manifest (``example, file, balls, min_depth_separation``).
        scene_of: example to its scene (:func:`neurender.metaballs.data.read_scenes`).
    """
    rows, showcase = [], None
    for _, ex in tqdm(manifest.sort_values("example").iterrows(), total=len(manifest)):
        parts = ab.read_ab(Path(test_dir) / ex["file"])
        gt = parts["target"]
        scene = scene_of[int(ex["example"])]
        preds = {
            label: r(r.inputs(scene, parts["inputs"])[None])[0] for label, r in renderers.items()
        }
        preds.update(baselines(scene, width))
        keys = {
            "example": int(ex["example"]),
            "balls": int(ex["balls"]),
            "min_depth_separation": ex["min_depth_separation"],
        }
        for model, pred in preds.items():
            rows += tidy_rows(
                "metaballs", TEST_DATASET, model, "test", example_metrics(pred, gt), **keys
            )
        if showcase is None or ex["balls"] > showcase.balls:  # show the busiest scene
            showcase = Showcase(int(ex["balls"]), parts["inputs"], gt, preds)
    return pd.DataFrame(rows), showcase


def mean_metrics(frame: pd.DataFrame) -> pd.DataFrame:
    """Tidy per-model means over the examples of :func:`score_test_set`'s rows, empty
    frames left out (they have no scores), then per model the number of empty frames
    (metric :data:`~neurender.metaballs.EMPTY_FRAMES`)."""
    keys = ["method", "dataset", "model", "split", "metric"]
    empty = frame["metric"] == EMPTY_FRAME
    means = frame[~empty].groupby(keys, as_index=False, sort=False)["value"].mean()
    counts = frame[empty].groupby(keys, as_index=False, sort=False)["value"].sum()
    return pd.concat([means, counts.assign(metric=EMPTY_FRAMES)], ignore_index=True)


def budget_rows(checkpoints: dict[str, str]) -> pd.DataFrame:
    """Tidy rows of each network's training budget (epochs trained), beside its scores."""
    rows = []
    for name, path in checkpoints.items():
        rows += tidy_rows("metaballs", TEST_DATASET, name, "test", {"epochs": epochs_trained(path)})
    return pd.DataFrame(rows)


def binned(frame: pd.DataFrame, column: str, edges: list[float]) -> pd.DataFrame:
    """Mean of each metric per model in bins of ``column`` (e.g. balls, depth separation);
    of :data:`~neurender.metaballs.EMPTY_FRAME`, the share of empty frames."""
    bins = pd.cut(frame[column], edges, include_lowest=True)
    return (
        frame.assign(bin=bins.astype(str))
        .groupby(["model", "bin", "metric"], observed=True, as_index=False)["value"]
        .mean()
    )


def accuracy_by_scene(frame: pd.DataFrame) -> pd.DataFrame:
    """:func:`binned` means by number of balls and by depth gap of overlapping balls
    (examples without overlaps left out), column ``by`` naming which."""
    edges = [*BALL_EDGES[:-1], max(int(frame["balls"].max()), BALL_EDGES[-1])]
    by_balls = binned(frame, "balls", edges).assign(by="balls")
    gaps = frame.dropna(subset=["min_depth_separation"])
    by_gap = binned(gaps, "min_depth_separation", GAP_EDGES).assign(by="min_depth_separation")
    return pd.concat([by_balls, by_gap], ignore_index=True)
