"""Figures of the metaballs stage: example AB images, the held-out comparison (thesis Fig.
7.2), accuracy against scene complexity, the demo (GIF and strip), temporal stability,
frame time against the number of balls and the user's scenes.

Images are tensors ``(C, W, W)`` in [0, 1] (G-buffer stacks as
:mod:`neurender.metaballs.gbuffers`) shown as they are.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import torch

from neurender import io
from neurender.metaballs import ab, evaluate, gbuffers
from neurender.metaballs.demo import RAY_MARCHING
from neurender.metaballs.evaluate import Showcase
from neurender.metaballs.speed import RAY_MARCHER
from neurender.plots import plt, save_figure


def _hwc(image: torch.Tensor) -> np.ndarray:
    """``(C, H, W)`` tensor to an ``(H, W, C)`` array for ``imshow``."""
    return image.permute(1, 2, 0).numpy()


def examples_figure(files: list[Path], path: str) -> None:
    """One row per AB example: input colour and depth, target colour, depth and normal."""
    fig, axes = plt.subplots(len(files), 1, figsize=(7.5, 2.6 * len(files)), squeeze=False)
    for ax, f in zip(axes[:, 0], files, strict=True):
        x = ab.read_ab(f)
        circles, target = x["inputs"], x["target"]
        panels = [
            circles[:3],
            circles[3:].expand(3, -1, -1),
            target[gbuffers.COLOUR],
            target[gbuffers.DEPTH].expand(3, -1, -1),
            target[gbuffers.NORMAL],
        ]
        ax.imshow(_hwc(torch.cat(panels, 2)))
        ax.set_title(
            f"{f.stem}: input colour | input depth | target colour | target depth | target normal",
            fontsize=7,
        )
        ax.axis("off")
    fig.tight_layout()
    save_figure(fig, path)


def overlap_image(pred: torch.Tensor, gt: torch.Tensor) -> np.ndarray:
    """Thesis Fig. 7.2 ``(W, W, 3)``: true silhouette red, predicted green, agreement yellow
    (silhouettes by the normal buffer)."""
    img = np.zeros((*gt.shape[1:], 3), np.float32)
    img[..., 0] = gbuffers.silhouette_normal(gt).numpy()
    img[..., 1] = gbuffers.silhouette_normal(pred).numpy()
    return img


def comparison_figure(showcase: Showcase, path: str) -> None:
    """Thesis Fig. 7.2: normals, silhouette overlap and enhanced differences per model."""
    preds, gt = showcase.predictions, showcase.truth
    fig, axes = plt.subplots(len(preds), 5, figsize=(11, 2.4 * len(preds)), squeeze=False)
    for row, (model, pred) in zip(axes, preds.items(), strict=True):
        difference = (pred[gbuffers.COLOUR] - gt[gbuffers.COLOUR]).abs() * 4
        panels = [
            (_hwc(showcase.circles[:3]), "input circles"),
            (_hwc(gt[gbuffers.NORMAL]), "ray-marched normals"),
            (_hwc(pred[gbuffers.NORMAL]), f"{model}: normals"),
            (overlap_image(pred, gt), "overlap: red truth, green predicted"),
            (_hwc(difference.clamp(0, 1)), "colour difference x4"),
        ]
        for ax, (img, title) in zip(row, panels, strict=True):
            ax.imshow(img)
            ax.set_title(title, fontsize=7)
            ax.axis("off")
    fig.tight_layout()
    save_figure(fig, path)


def accuracy_figure(by_scene: pd.DataFrame, path: str) -> None:
    """IoU and normal error per model against the number of balls and the depth gap of
    overlapping balls (:func:`neurender.metaballs.evaluate.accuracy_by_scene`)."""
    fig, axes = plt.subplots(2, 2, figsize=(9, 6))
    labels = {
        "balls": "number of balls",
        "min_depth_separation": "depth gap of overlapping balls (world units)",
    }
    for col, (by, label) in enumerate(labels.items()):
        for row, metric in enumerate(("iou_depth", "normal_error_mean_deg")):
            ax = axes[row, col]
            sel = by_scene[(by_scene.by == by) & (by_scene.metric == metric)]
            for model, part in sel.groupby("model", sort=False):
                ax.plot(part["bin"], part["value"], "o-", label=model)
            ax.set_xlabel(label)
            ax.set_ylabel(metric)
            ax.tick_params(axis="x", labelsize=7)
    axes[0, 0].legend(fontsize=7)
    fig.suptitle("Metaballs: accuracy against scene complexity (held-out scenes)")
    fig.tight_layout()
    save_figure(fig, path)


def demo_frames(pictures: list[torch.Tensor]) -> list[np.ndarray]:
    """The demo's pictures ``(3, H, W)`` in [0, 1] as ``(H, W, 3)`` uint8 frames."""
    return [io.to_uint8(_hwc(p)) for p in pictures]


def demo_gif(frames: list[np.ndarray], path: str, ms_per_frame: int = 80) -> None:
    """An endlessly looping GIF of uint8 frames ``(H, W, 3)``."""
    from PIL import Image

    images = [Image.fromarray(f) for f in frames]
    with io.atomic_path(path) as tmp:
        images[0].save(tmp, save_all=True, append_images=images[1:], duration=ms_per_frame, loop=0)


def demo_strip(frames: list[np.ndarray], path: str, count: int = 4) -> None:
    """``count`` frames evenly spaced from the first, stacked top to bottom, as a PNG."""
    io.write_png(path, np.concatenate(frames[:: max(1, len(frames) // count)][:count], 0))


def stability_figure(flips: pd.DataFrame, path: str) -> None:
    """Silhouette pixels flipped since the last frame, per model and for ray marching
    (:func:`neurender.metaballs.demo.silhouette_flips`)."""
    fig, ax = plt.subplots(figsize=(5, 3))
    for n in flips.columns.drop("frame"):
        ax.plot(flips.frame, flips[n], "s--" if n == RAY_MARCHING else "o-", label=n)
    ax.set_xlabel("frame")
    ax.set_ylabel("silhouette pixels flipped since last frame")
    ax.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, path)


def frame_time_figure(balls: pd.DataFrame, path: str) -> None:
    """Milliseconds per frame against the number of balls, log scale
    (:func:`neurender.metaballs.speed.frame_time_vs_balls`)."""
    fig, ax = plt.subplots(figsize=(5, 3))
    for name, part in balls.groupby("model", sort=False):
        label = name if name == RAY_MARCHER else f"{name}: inputs + network"
        style = "s--" if name == RAY_MARCHER else "o-"
        ax.semilogy(part.balls, part.ms_per_frame, style, label=label)
    ax.set_xlabel("number of balls")
    ax.set_ylabel("ms per frame")
    ax.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, path)


def user_scenes_figure(shown: dict[str, Showcase], models: list[str], path: str) -> None:
    """ "Your scenes": one row per scene, the input circles, the ray marcher's colour and
    normals, then each of ``models``' normals titled with its silhouette IoU (by the
    normal buffer, thesis 7.1)."""
    cols = 3 + len(models)
    fig, axes = plt.subplots(
        len(shown), cols, figsize=(1.9 * cols, 2.0 * len(shown)), squeeze=False
    )
    for row, (label, show) in zip(axes, shown.items(), strict=True):
        gt = show.truth
        panels = [
            (_hwc(show.circles[:3]), f"scene {label} ({show.balls} balls): circles"),
            (_hwc(gt[gbuffers.COLOUR]), "ray marcher: colour"),
            (_hwc(gt[gbuffers.NORMAL]), "ray marcher: normals"),
        ]
        for model in models:
            pred = show.predictions[model]
            iou = evaluate.iou(gbuffers.silhouette_normal(pred), gbuffers.silhouette_normal(gt))
            score = "nothing in view" if math.isnan(iou) else f"IoU {iou:.2f}"
            panels.append((_hwc(pred[gbuffers.NORMAL]), f"{model} ({score})"))
        for ax, (img, title) in zip(row, panels, strict=True):
            ax.imshow(np.clip(img, 0, 1))
            # The scene label is the user's text as written: "$x$" is not math to typeset.
            ax.set_title(title, fontsize=7, parse_math=False, usetex=False)
            ax.axis("off")
    fig.tight_layout()
    save_figure(fig, path)
