"""The metaballs stage's summary tables: statistics of the examples and the targets.

Targets (thresholds from the metaballs' ``targets.csv``, beside this module): per network a
silhouette IoU and a mean normal error (stricter at the paper's scale, ``W >= 512``),
better than the isolated-sphere baseline on every metric and than the refined impostors
(the strongest no-learning baseline) on IoU and normal error, and a frame (inputs + network)
faster than ray marching at the most balls and than the cheapest ray marcher of its quality
(:mod:`neurender.metaballs.equal_quality`).
"""

from __future__ import annotations

import math

import pandas as pd

from neurender import equal_quality as shared
from neurender.metaballs import EMPTY_FRAMES, REFINED_BASELINE
from neurender.tables import Target, lookup, target_table, threshold, tidy_rows

#: Image width from which the paper-scale thresholds apply (the thesis used 512).
PAPER_SCALE_WIDTH = 512
#: The baseline every network must beat, and the suffix of every no-learning baseline.
BASELINE = "isolated spheres"
BASELINE_SUFFIX = " spheres"
#: The metrics every network is checked on against the strongest no-learning baseline
#: (:data:`neurender.metaballs.REFINED_BASELINE`): those of the equal-quality sweep.
STRONGEST_BASELINE_METRICS = ("iou_depth", "normal_error_mean_deg")
#: Rows of the metrics table that state a network's training budget, not a score.
BUDGET_METRICS = {"epochs"}
#: Rows of the metrics table that are no score: the budget and the count of empty frames.
NOT_SCORES = BUDGET_METRICS | {EMPTY_FRAMES}
#: Metric prefixes where lower is better (the rest: higher is better).
LOWER_IS_BETTER = ("l1_", "depth_error", "normal_error")


def data_rows(manifest: pd.DataFrame) -> list[dict]:
    """Tidy statistics of one split's examples from its manifest
    (:mod:`neurender.metaballs.data`)."""
    stats = {
        "examples": len(manifest),
        "balls_mean": manifest["balls"].mean(),
        "coverage_mean": manifest["coverage"].mean(),
        "min_depth_separation_median": manifest["min_depth_separation"].median(),
        "raymarch_seconds_per_example": manifest["seconds"].mean(),
    }
    split = str(manifest["split"].iloc[0])
    return tidy_rows("metaballs", "examples", "ray marcher", split, stats)


def accuracy_targets(metrics: pd.DataFrame, width: int) -> list[Target]:
    """Per network (every model of ``metrics`` but the baselines): IoU, normal error,
    every metric against the isolated spheres, and IoU and normal error against the
    refined impostors (where the table has them)."""
    scale = "_paper_scale" if width >= PAPER_SCALE_WIDTH else ""
    iou_min = threshold("metaballs", f"iou_depth{scale}")
    angle_max = threshold("metaballs", f"normal_error_deg{scale}")
    models = [m for m in metrics["model"].unique() if not m.endswith(BASELINE_SUFFIX)]
    out = []
    for model in models:
        iou = lookup(metrics, model=model, metric="iou_depth")
        angle = lookup(metrics, model=model, metric="normal_error_mean_deg")
        out += [
            Target(model, f"silhouette IoU (depth) >= {iou_min:g}", iou, iou >= iou_min),
            Target(model, f"mean normal error <= {angle_max:g} deg", angle, angle <= angle_max),
        ]
        scores = set(metrics["metric"]) - NOT_SCORES
        for metric in sorted(scores):
            ours = lookup(metrics, model=model, metric=metric)
            base = lookup(metrics, model=BASELINE, metric=metric)
            better = ours < base if metric.startswith(LOWER_IS_BETTER) else ours > base
            check = f"better than {BASELINE} on {metric} ({base:.4g})"
            out.append(Target(model, check, ours, bool(better)))
        for metric in STRONGEST_BASELINE_METRICS:
            best = lookup(metrics, model=REFINED_BASELINE, metric=metric)
            if math.isnan(best):
                continue
            ours = lookup(metrics, model=model, metric=metric)
            better = ours < best if metric.startswith(LOWER_IS_BETTER) else ours > best
            check = f"better than {REFINED_BASELINE} (no learning) on {metric} ({best:.4g})"
            out.append(Target(model, check, ours, bool(better)))
    return out


def speed_targets(timing: pd.DataFrame) -> list[Target]:
    """Per network: its frame at least the threshold's times faster than ray marching."""
    least = threshold("metaballs", "speedup")
    speedups = timing[timing["metric"].str.startswith("speedup_at_")]
    return [
        Target(
            s.model,
            f"frame >= {least:g}x faster than ray marching ({s.metric})",
            float(s.value),
            float(s.value) >= least,
        )
        for s in speedups.itertuples()
    ]


def equal_quality_targets(equal: pd.DataFrame) -> list[Target]:
    """Per network (not the no-learning renderers): its frame at least the threshold's
    times faster than the cheapest ray marcher of its quality (``equal_quality.csv``, the
    shared rule's targets: :func:`neurender.equal_quality.targets`)."""
    least = threshold("metaballs", "equal_quality_speedup")
    networks = equal[~equal["model"].str.endswith(BASELINE_SUFFIX)]
    return shared.targets(networks, least, "ray marcher")


def targets(
    metrics: pd.DataFrame, timing: pd.DataFrame, equal: pd.DataFrame, width: int
) -> pd.DataFrame:
    """The stage's targets (:data:`neurender.tables.TARGET_COLUMNS`) from ``metrics.csv``,
    ``timing.csv`` and ``equal_quality.csv`` at image width ``width``."""
    checks = accuracy_targets(metrics, width) + speed_targets(timing)
    return target_table("metaballs", checks + equal_quality_targets(equal))
