"""The networks against the cheapest ray marcher of equal quality, as DeepPRT's
equal-quality ratio (:mod:`neurender.prt.equal_quality`).

A cheaper ray marcher (:class:`March`) has a larger step floor, fewer bisections of the
bracketed crossing, or a lower resolution (``round(resolution W)`` pixels a side,
upsampled to ``W`` by nearest neighbour, so silhouettes stay binary). Its quality is that
of the test set's metrics (:func:`neurender.metaballs.evaluate.example_metrics`):
silhouette IoU by depth (``iou_depth``, higher is better) and the mean normal error in
degrees (``normal_error_mean_deg``, lower is better), against the same ray-marched targets
as the networks, on the same first test examples. The fastest setting
whose two means both reach a network's is its equal-quality marcher (the shared rule,
:mod:`neurender.equal_quality`, with its bounds); the ratio of its milliseconds per frame
to the network's (inputs and network, as the speed table) is the equal-quality speed-up.
The strongest no-learning renderer (:data:`neurender.metaballs.REFINED_BASELINE`) is
timed and compared alike, its frame the whole render. Times are wall-clock medians of
:func:`neurender.timing.timed`, the marchers' and the networks' on the same scenes,
machine and threads.
"""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Callable, Iterable, Sequence

import pandas as pd
import torch
from matplotlib.ticker import NullFormatter, ScalarFormatter

from neurender import equal_quality as shared
from neurender.metaball import BISECTIONS, MIN_STEP, Scene
from neurender.metaballs import (
    EQUAL_QUALITY_BISECTIONS,
    EQUAL_QUALITY_MIN_STEPS,
    EQUAL_QUALITY_RESOLUTIONS,
    REFINED_BASELINE,
    evaluate,
    raymarch,
)
from neurender.metaballs.evaluate import TEST_DATASET
from neurender.plots import plt, save_figure
from neurender.timing import timed

#: The two metrics of equal quality and whether higher is better.
QUALITY = {"iou_depth": True, "normal_error_mean_deg": False}
#: The ``model`` and ``split`` of the sweep's rows in :func:`table`.
RAY_MARCHER = "ray marcher"
SPLIT = shared.SPLIT


@dataclasses.dataclass(frozen=True)
class March:
    """One ray-marcher setting: step floor ``min_step`` (world units), ``bisections`` and
    ``resolution`` (the marched width as a fraction of the image's, in (0, 1])."""

    min_step: float = MIN_STEP
    bisections: int = BISECTIONS
    resolution: float = 1.0

    @property
    def label(self) -> str:
        return f"step {self.min_step:g}, {self.bisections} bisections, {self.resolution:g} width"


#: The reference ray marcher: the targets' own.
REFERENCE = March()


def sweep(
    min_steps: Iterable[float] = EQUAL_QUALITY_MIN_STEPS,
    bisections: Iterable[int] = EQUAL_QUALITY_BISECTIONS,
    resolutions: Iterable[float] = EQUAL_QUALITY_RESOLUTIONS,
) -> list[March]:
    """Every combination of the given values, the reference first when it is among them."""
    settings = [March(*v) for v in itertools.product(min_steps, bisections, resolutions)]
    return sorted(settings, key=lambda m: m != REFERENCE)


def render(scene: Scene, width: int, setting: March) -> torch.Tensor:
    """The ``(7, W, W)`` G-buffer stack of ``setting``'s ray marcher (float32, [0, 1])."""
    if not 0 < setting.resolution <= 1:
        raise ValueError(f"ray-marcher resolution {setting.resolution}: expected (0, 1]")
    marched = max(1, round(setting.resolution * width))
    stack = raymarch.render_gbuffers(
        scene, marched, min_step=setting.min_step, bisections=setting.bisections
    ).stack()
    if marched == width:
        return stack
    return torch.nn.functional.interpolate(stack[None], size=(width, width), mode="nearest")[0]


def score_settings(
    examples: Sequence[tuple[Scene, torch.Tensor]],
    width: int,
    settings: Sequence[March],
    repeats: int = 1,
) -> pd.DataFrame:
    """One row per setting: ``min_step, bisections, resolution, label``, ``ms_per_frame``
    (the mean over the examples of the median of ``repeats`` renders) and the means over
    the examples of :data:`QUALITY`'s metrics against each example's target ``(7, W, W)``."""
    rows = []
    for setting in settings:
        seconds, metrics = [], []
        for scene, target in examples:
            pred, s = timed(render, scene, width, setting, repeats=repeats)
            seconds.append(s)
            metrics.append(evaluate.example_metrics(pred, target))
        # An empty frame has no scores (NaN here): left out of the means, as the networks'.
        means = pd.DataFrame(metrics).reindex(columns=list(QUALITY)).mean()
        rows.append(
            {
                **dataclasses.asdict(setting),
                "label": setting.label,
                "ms_per_frame": 1e3 * sum(seconds) / len(seconds),
                **means.to_dict(),
            }
        )
    return pd.DataFrame(rows)


def network_ms_per_frame(
    draw: Callable[[Scene], torch.Tensor],
    network: Callable[[torch.Tensor], torch.Tensor],
    scenes: Sequence[Scene],
    repeats: int = 5,
) -> float:
    """Mean over ``scenes`` of a network's median milliseconds per frame: drawing its
    input ``(C, W, W)`` and running it on a batch of one (as
    :func:`neurender.metaballs.speed.frame_time_vs_balls`; for a
    :class:`~neurender.metaballs.renderer.MetaballRenderer` ``r``: ``r.inputs, r``)."""
    total = 0.0
    for scene in scenes:
        x, t_in = timed(draw, scene, repeats=repeats, warmup=1)
        _, t_net = timed(network, x[None], repeats=repeats, warmup=1)
        total += t_in + t_net
    return 1e3 * total / len(scenes)


def renderer_ms_per_frame(
    render: Callable[[Scene], torch.Tensor], scenes: Sequence[Scene], repeats: int = 5
) -> float:
    """Mean over ``scenes`` of the median milliseconds of a no-learning renderer's whole
    frame ``render(scene)`` (e.g. :func:`neurender.metaballs.refined.refined_spheres`)."""
    total = sum(timed(render, scene, repeats=repeats, warmup=1)[1] for scene in scenes)
    return 1e3 * total / len(scenes)


def settings(scores: pd.DataFrame) -> pd.DataFrame:
    """:func:`score_settings`' rows as the shared rule reads them (:mod:`neurender.
    equal_quality`): ``setting`` (the marcher's label), ``ms_per_frame`` and the quality."""
    return scores[["label", "ms_per_frame", *QUALITY]].rename(columns={"label": "setting"})


def cheapest(scores: pd.DataFrame, target: dict[str, float]) -> shared.Pick:
    """The fastest marcher of :func:`score_settings`' ``scores`` that reaches ``target``'s
    quality on both metrics, or the bound (:func:`neurender.equal_quality.pick`)."""
    return shared.pick(settings(scores), target, QUALITY)


def network_targets(frame: pd.DataFrame, examples: Sequence[int]) -> dict[str, dict[str, float]]:
    """Per model its :data:`QUALITY` means over ``examples`` in the evaluation's tidy
    per-example rows (``metrics_examples.csv``: ``example, model, metric, value``)."""
    part = frame[frame["example"].isin(examples) & frame["metric"].isin(list(QUALITY))]
    means = part.groupby(["model", "metric"], sort=False)["value"].mean()
    return {model: means[model].to_dict() for model in part["model"].unique()}


def table(
    scores: pd.DataFrame, networks: dict[str, tuple[dict[str, float], float]]
) -> pd.DataFrame:
    """The equal-quality table (:func:`neurender.equal_quality.table`: model
    :data:`RAY_MARCHER` per setting of :func:`score_settings`, of the test set): per
    network (``networks``: name to its quality and ms per frame) beside the shared rows its
    ``speedup_vs_reference_marcher``."""
    reference_ms = float(scores.loc[scores["label"] == REFERENCE.label, "ms_per_frame"].iloc[0])
    rows = {
        name: shared.Network(means, ms, {"speedup_vs_reference_marcher": reference_ms / ms})
        for name, (means, ms) in networks.items()
    }
    return shared.table("metaballs", TEST_DATASET, RAY_MARCHER, settings(scores), rows, QUALITY)


def quality_figure(
    scores: pd.DataFrame,
    networks: dict[str, tuple[dict[str, float], float]],
    path: str,
) -> None:
    """Each :data:`QUALITY` metric against milliseconds per frame (log scale): the sweep's
    settings by resolution, the reference ringed, each network a star (the no-learning
    refined impostors a diamond) and the cheapest marcher of its quality crossed.

    Args:
        networks: name to ``(its metric means, its ms per frame)``.
    """
    fig, axes = plt.subplots(1, len(QUALITY), figsize=(10, 4))
    for ax, (metric, higher) in zip(axes, QUALITY.items(), strict=True):
        for resolution, part in scores.groupby("resolution", sort=False):
            label = f"ray marcher, {resolution:g} width"
            ax.scatter(part["ms_per_frame"], part[metric], s=14, label=label)
        ref = scores[scores["label"] == REFERENCE.label]
        ax.scatter(ref["ms_per_frame"], ref[metric], s=90, facecolors="none", edgecolors="k")
        for name, (means, ms) in networks.items():
            learned = name != REFINED_BASELINE
            marker, label = ("*", name) if learned else ("D", f"{name} (no learning)")
            star = ax.scatter([ms], [means[metric]], marker=marker, s=160, label=label, zorder=3)
            best = cheapest(scores, means)
            if best.bound != shared.LOWER:
                row = settings(scores).set_index("setting").loc[best.setting]
                ax.scatter(
                    [row["ms_per_frame"]],
                    [row[metric]],
                    marker="x",
                    s=80,
                    color=star.get_facecolor()[0],
                    zorder=3,
                )
        ax.set_xscale("log")
        ax.xaxis.set_major_formatter(ScalarFormatter())
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.set_xlabel("ms per frame")
        ax.set_ylabel(f"{metric} ({'higher' if higher else 'lower'} is better)")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7)
    fig.suptitle("Ray marchers of every cost against the networks (ringed: the reference)")
    fig.tight_layout()
    save_figure(fig, path)
