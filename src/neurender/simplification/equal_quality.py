"""Ours against the classic pipeline at equal quality, in triangles.

The paper's currency is triangles: it compares its optimised mesh with the classic
pipeline (a QEM decimation and a normal map baked from the detailed model, Simplygon's in
Fig. 3) at the same triangle count. The equal-quality question is how many triangles the
classic pipeline needs to look as good as ours. Time is no measure of it here: Mitsuba's
ray tracing barely depends on the triangle count.

The classic pipeline is swept over triangle budgets, ``simplification.
equal_quality_multiples`` times the case's budget (those below the detailed reference's
triangles): each is made exactly as the preparation makes the ``baked`` variant at ours'
budget (:func:`classic`: :func:`neurender.simplification.mesh_ops.decimate`, the xatlas
atlas, :func:`neurender.simplification.bake.bake` with the asset's colour and normal, the
maps stored as 16-bit textures), rendered from the held-out test views as the evaluation
renders every variant (:func:`neurender.simplification.evaluate.render_held_out`) and
scored by the evaluation's metrics (:func:`neurender.simplification.evaluate.
image_metrics`), means over the views. So the sweep's ``1x`` setting is the evaluation's
``baked`` variant.

The quality (:data:`QUALITY`) is all four metrics: PSNR and SSIM (higher is better), FLIP
and the silhouette coverage error (lower is better); a setting reaches ours when it is at
least as good on each. The shared rule (:mod:`neurender.equal_quality`, cost
:data:`neurender.equal_quality.TRIANGLES`) picks the setting of fewest triangles that
reaches ours' held-out quality (``metrics.csv``); the ratio of its triangles to ours' is
``equal_quality_triangle_ratio``: the classic pipeline needs that many times ours'
triangles, a lower bound where no budget of the sweep reaches ours, an upper bound where
the smallest already does.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from types import ModuleType

import numpy as np
import pandas as pd
from matplotlib.ticker import FixedFormatter, FixedLocator, NullLocator

from neurender import equal_quality as shared
from neurender.plots import plt, save_figure
from neurender.simplification import bake, evaluate, formats, mesh_ops, render, summary
from neurender.simplification.assets import Asset
from neurender.simplification.mesh_ops import LowPolyMesh

log = logging.getLogger(__name__)

#: Metric -> higher is better: the evaluation's four, every one of which a setting must
#: reach.
QUALITY = {"psnr": True, "ssim": True, "flip": False, "coverage_error": False}
#: The model of the sweep's rows, and what sentences call it.
CLASSIC, CLASSIC_WORDS = "classic", summary.CLASSIC_WORDS
#: Ours' model (``metrics.csv``'s and the table's).
OURS = "ours"
#: QEM's smallest target (:func:`neurender.simplification.mesh_ops.decimate` needs a
#: mesh to simplify).
MIN_TRIANGLES = 4


def budgets(multiples: Sequence[float], budget: int, detailed: int) -> list[tuple[float, int]]:
    """``(multiple, triangles)`` of each of ``multiples`` times the case's ``budget``,
    rounded, in increasing order, those below the ``detailed`` reference's triangles (and
    at least :data:`MIN_TRIANGLES`); a budget reached by two multiples once.

    Raises:
        ValueError: naming the multiples when none is left.
    """
    found: dict[int, float] = {}
    for m in sorted(multiples):
        triangles = round(m * budget)
        if MIN_TRIANGLES <= triangles < detailed:
            found.setdefault(triangles, m)
    if not found:
        raise ValueError(
            f"simplification.equal_quality_multiples = {list(multiples)} times the budget of "
            f"{budget} triangles: none is below the reference's {detailed} triangles; "
            "expected at least one"
        )
    return [(m, t) for t, m in found.items()]


def label(triangles: int) -> str:
    """A setting's name: its triangle count."""
    return f"{triangles} triangles"


def classic(
    asset: Asset, triangles: int, size: int
) -> tuple[LowPolyMesh, np.ndarray | float, np.ndarray]:
    """The classic pipeline at a budget of ``triangles``: the QEM decimation of the
    asset's detailed surface, its xatlas atlas and the classic bakes at ``size^2`` texels,
    as :func:`neurender.simplification.jobs.simplification_prepare` makes them; the atlas
    mesh, its albedo (the asset's uniform grey, or the baked map) and normal map as the
    evaluation reads the ``baked`` variant's (16-bit, :func:`neurender.simplification.
    formats.stored`)."""
    v, f = mesh_ops.decimate(asset.vertices, asset.faces, triangles)
    low = mesh_ops.uv_atlas(v, f, size)
    normal_map, colour_map = bake.bake(
        low, asset.vertices, asset.faces, size, asset.colour_fn, asset.normal_fn
    )
    albedo = asset.albedo if asset.albedo is not None else formats.stored(colour_map)
    return low, albedo, formats.stored(normal_map)


def score_sweep(
    mi: ModuleType,
    dr: ModuleType,
    case: str,
    asset: Asset,
    test_views: list,
    references: np.ndarray,
    cfg: Mapping,
) -> pd.DataFrame:
    """One row per budget of ``cfg["equal_quality_multiples"]`` (:func:`budgets` of the
    asset's): ``setting``, ``multiple``, ``triangles`` (the decimation's count) and the
    means over the held-out views of :data:`QUALITY`'s metrics against ``references``
    (``(N, W, W, 4)``), the classic mesh made by :func:`classic` and rendered by
    :func:`neurender.simplification.evaluate.render_held_out` with ``cfg``'s keys."""
    rows = []
    for multiple, budget in budgets(
        cfg["equal_quality_multiples"], asset.triangles, len(asset.faces)
    ):
        low, albedo, normal_map = classic(asset, budget, cfg["texture_size"])
        shape = render.atlas_shape(mi, low, render.material(mi, albedo, normal_map))
        images = evaluate.render_held_out(
            mi, dr, shape, test_views, cfg, f"{case} classic {budget}"
        )
        scores = [evaluate.image_metrics(a, b) for a, b in zip(images, references, strict=True)]
        means = {m: float(np.mean([s[m] for s in scores])) for m in QUALITY}
        triangles = len(low.faces)
        rows.append(
            {"setting": label(triangles), "multiple": multiple, "triangles": triangles, **means}
        )
    return pd.DataFrame(rows)


def ours(metrics: pd.DataFrame, case: str) -> dict[str, float]:
    """Ours' held-out quality of ``case`` from the evaluation's means (``metrics.csv``:
    ``dataset, model, metric, value``), :data:`QUALITY`'s metrics."""
    mine = metrics[(metrics["dataset"] == case) & (metrics["model"] == OURS)]
    value = mine.set_index("metric")["value"]
    missing = [m for m in QUALITY if m not in value.index]
    if missing:
        raise ValueError(
            f"metrics have no {missing} of ours for case {case!r}; expected {list(QUALITY)}"
        )
    return {m: float(value[m]) for m in QUALITY}


def table(
    case: str, scores: pd.DataFrame, quality: Mapping[str, float], triangles: int
) -> pd.DataFrame:
    """The equal-quality table of one case (:func:`neurender.equal_quality.table`, cost
    :data:`neurender.equal_quality.TRIANGLES`): the classic sweep's rows (model
    :data:`CLASSIC`) and ours' (its ``triangles`` and ``quality``, the ratio and the
    picked setting's triangles)."""
    networks = {OURS: shared.Network(quality, float(triangles))}
    chosen = shared.pick(scores, quality, QUALITY, shared.TRIANGLES)
    log.info(
        "%s: %s needs %s ours' %d triangles (against %s)",
        case,
        CLASSIC_WORDS,
        shared.stated(chosen.cost / triangles, chosen.bound),
        triangles,
        chosen.setting,
    )
    return shared.table(
        "simplification", case, CLASSIC, scores, networks, QUALITY, shared.TRIANGLES
    )


def quality_figure(
    sweeps: Mapping[str, pd.DataFrame],
    ours_quality: Mapping[str, Mapping[str, float]],
    ours_triangles: Mapping[str, int],
    path: str,
) -> None:
    """One row per case, one panel per metric of :data:`QUALITY`: the classic pipeline's
    value against its triangles (log scale, ticks at the budgets), ours as a star with its
    value as a dashed line, the pick circled; each row's first panel titled by the ratio
    as sentences state it."""
    cases = list(sweeps)
    fig, axes = plt.subplots(
        len(cases), len(QUALITY), figsize=(3.2 * len(QUALITY), 2.8 * len(cases)), squeeze=False
    )
    for row, case in enumerate(cases):
        scores, quality, triangles = sweeps[case], ours_quality[case], ours_triangles[case]
        chosen = shared.pick(scores, quality, QUALITY, shared.TRIANGLES)
        picked = scores[scores["setting"] == chosen.setting].iloc[0]
        ratio = shared.stated(chosen.cost / triangles, chosen.bound)
        ticks = sorted({*scores["triangles"].astype(int), int(triangles)})
        for col, (ax, metric) in enumerate(zip(axes[row], QUALITY, strict=True)):
            ax.plot(scores["triangles"], scores[metric], "o-", ms=4, label=CLASSIC_WORDS)
            ax.scatter(
                [triangles], [quality[metric]], marker="*", s=160, color="C3", zorder=3, label=OURS
            )
            ax.axhline(quality[metric], color="C3", ls="--", lw=0.8)
            ax.scatter(
                [picked["triangles"]],
                [picked[metric]],
                s=120,
                facecolors="none",
                edgecolors="k",
                zorder=3,
                label=f"pick ({chosen.bound})",
            )
            ax.set_xscale("log")
            ax.xaxis.set_major_locator(FixedLocator(ticks))
            ax.xaxis.set_minor_locator(NullLocator())
            ax.xaxis.set_major_formatter(FixedFormatter([str(t) for t in ticks]))
            ax.tick_params(axis="x", labelsize=7, labelrotation=45)
            ax.set_xlabel("triangles", fontsize=8)
            title = f"{case}: {metric}"
            if col == 0:
                title = f"{case}: classic needs {ratio}\n{metric}"
            ax.set_title(title, fontsize=9)
    axes[0, 0].legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, path)
