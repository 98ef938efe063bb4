"""Figures of the NDR stage: the buffers (paper Fig. 1), the comparison (Figs. 5/6), the
relighting (Fig. 3 (d)) and the training curves.

HDR images are shown Reinhard tone-mapped with gamma 2.2 (:func:`neurender.display.tonemap`);
tensors are ``(3, H, W)`` linear radiance, EXR channels as in :mod:`neurender.ndr.buffers`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import torch

from neurender import io
from neurender.display import reinhard, tonemap
from neurender.ndr.model import SHADING_INPUT
from neurender.ndr.variants import VARIANTS
from neurender.plots import plt, save_figure

#: Methods of the comparison figure, left to right (those that ran).
COMPARED = (
    SHADING_INPUT,
    "ndr",
    "ndr_direct",
    "single_decoder",
    "no_intrinsic",
    "no_shading",
    "pix2pix",
)
#: Buffer panels of the buffers figure, left to right.
BUFFER_PANELS = ("N", "D", "R", "S_D", "S_S", "A_D", "A_S", "I_D", "I_S", "I_R")


def _show(x: torch.Tensor) -> np.ndarray:
    """HDR ``(3, H, W)`` to a displayable ``(H, W, 3)`` in [0, 1]."""
    return tonemap(x).permute(1, 2, 0).numpy()


def _rgb(c: dict[str, np.ndarray], group: str, suffix: str = "RGB") -> np.ndarray:
    return np.stack([c[f"{group}.{s}"] for s in suffix], -1)


def buffer_images(c: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """One sample's EXR channels as displayable images ``(H, W[, 3])`` in [0, 1]."""
    mask = c["mask"][..., None]
    images = {
        "N": (_rgb(c, "N", "XYZ") + 1) / 2 * mask,
        "D": c["D"],
        "R": c["R"],
        "A_D": _rgb(c, "A_D"),
        "A_S": _rgb(c, "A_S"),
    }
    hdr = {g: _rgb(c, g) for g in ("S_D", "S_S", "I_D", "I_S")}
    hdr["I_R"] = hdr["I_S"] * images["A_S"] + hdr["I_D"] * images["A_D"]
    return {**images, **{k: tonemap(v) for k, v in hdr.items()}}


def buffers_figure(folder: str, out: str, count: int = 3) -> None:
    """Paper Fig. 1 dataflow for the first ``count`` samples of a split folder: inputs,
    albedos, shading maps, I_R."""
    files = sorted(Path(folder).glob("*.exr"))[:count]
    fig, axes = plt.subplots(
        len(files),
        len(BUFFER_PANELS),
        figsize=(1.3 * len(BUFFER_PANELS), 1.4 * len(files)),
        squeeze=False,
    )
    for r, path in enumerate(files):
        images = buffer_images(io.read_exr(path))
        for col, name in enumerate(BUFFER_PANELS):
            ax = axes[r, col]
            img = np.clip(images[name], 0, 1)
            ax.imshow(img, cmap="gray" if img.ndim == 2 else None, vmin=0, vmax=1)
            ax.set_title(name if r == 0 else "", fontsize=8)
            ax.axis("off")
    fig.tight_layout()
    save_figure(fig, out)


def comparison_figure(
    buffers: dict[str, torch.Tensor],
    truth: dict[str, torch.Tensor],
    methods: dict[str, dict[str, torch.Tensor]],
    out: str,
    rows: int = 4,
) -> None:
    """Paper Figs. 5/6 style: buffers, ground truth, methods and NDR's error, one row per
    sample; the samples with the most occlusion (largest shading-input error) are shown.

    ``buffers``, ``truth`` and each method's predictions hold a test split ``(N, C, H, W)``.
    """
    b = buffers
    order = [m for m in COMPARED if m in methods]
    err = (reinhard(methods[SHADING_INPUT]["I_R"]) - reinhard(truth["I_R"])).abs() * b["mask"]
    picks = torch.argsort(err.flatten(1).sum(1), descending=True)[:rows].tolist()
    cols = 3 + len(order) + 1
    fig, axes = plt.subplots(
        len(picks), cols, figsize=(1.5 * cols, 1.6 * len(picks)), squeeze=False
    )
    for r, i in enumerate(picks):
        panels = [
            ("normals", ((b["N"][i] + 1) / 2 * b["mask"][i]).permute(1, 2, 0).numpy()),
            ("albedo A_D", b["A_D"][i].permute(1, 2, 0).numpy()),
            ("ground truth", _show(truth["I_R"][i])),
        ]
        panels += [(m.replace("_", " "), _show(methods[m]["I_R"][i])) for m in order]
        for c, (title, img) in enumerate(panels):
            axes[r, c].imshow(np.clip(img, 0, 1))
            axes[r, c].set_title(title if r == 0 else "", fontsize=7)
        if "ndr" in methods:
            diff = (reinhard(methods["ndr"]["I_R"][i]) - reinhard(truth["I_R"][i])).abs().mean(0)
            axes[r, -1].imshow(diff.numpy(), cmap="magma", vmin=0, vmax=0.2)
            axes[r, -1].set_title("|NDR - GT| (0-0.2)" if r == 0 else "", fontsize=7)
        for ax in axes[r]:
            ax.axis("off")
    fig.tight_layout()
    save_figure(fig, out)


def loss_figure(logs: dict[str, str], out: str) -> None:
    """Validation DSSIM of I_R (L1 for pix2pix) per epoch, one line per variant (name ->
    loss CSV of :func:`neurender.train.fit`)."""
    fig, ax = plt.subplots(figsize=(6, 3.5))
    for name, path in logs.items():
        h = io.read_csv(path, ["epoch", "split", "metric", "value"])
        metric = "l1" if VARIANTS[name].arch == "pix2pix" else "dssim_I_R"
        sel = h[(h.split == "val") & (h.metric == metric)]
        ax.plot(sel.epoch, sel.value, marker="o", ms=3, label=f"{name} ({metric})")
    ax.set_xlabel("epoch")
    ax.set_ylabel("validation loss term")
    ax.set_yscale("log")
    ax.legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, out)


def relighting_figure(
    degrees: list[float],
    truth: torch.Tensor,
    pred: torch.Tensor,
    coarse: torch.Tensor,
    dssim: pd.DataFrame,
    out: str,
) -> None:
    """One column per map rotation (``degrees``): Mitsuba, NDR and the shading input's
    ``I_R`` ``(T, 3, H, W)``, titled with the DSSIM rows (``model, rotation_deg, value``)."""
    score = dssim.set_index(["model", "rotation_deg"])["value"]
    turns = len(degrees)
    fig, axes = plt.subplots(3, turns, figsize=(1.7 * turns, 5.4), squeeze=False)
    for k, deg in enumerate(degrees):
        panels = (
            (f"Mitsuba, map +{deg:.0f} deg", truth[k]),
            (f"NDR (DSSIM {score[('ndr', deg)]:.3f})", pred[k]),
            (f"shading input ({score[(SHADING_INPUT, deg)]:.3f})", coarse[k]),
        )
        for r, (title, image) in enumerate(panels):
            axes[r, k].imshow(np.clip(_show(image), 0, 1))
            axes[r, k].set_title(title, fontsize=7)
            axes[r, k].axis("off")
    fig.tight_layout()
    save_figure(fig, out)


def user_objects_figure(
    labels: list[tuple[str, str, str]],
    buffers: dict[str, torch.Tensor],
    truth: dict[str, torch.Tensor],
    methods: dict[str, dict[str, torch.Tensor]],
    per_map: pd.DataFrame,
    out: str,
) -> None:
    """ "Your objects": one row per object and map set (its first map), left to right the
    albedo, Mitsuba's ``I_R``, NDR's and the shading input's (titled with their DSSIM of
    ``I_R``) and NDR's error.

    ``labels``: ``(object, map set, map)`` of every render, in the order of the
    ``(N, C, H, W)`` tensors; ``per_map``: the scores (columns ``model, object, map,
    metric, value``).
    """
    shown = {}
    for i, (name, map_set, _) in enumerate(labels):
        shown.setdefault((name, map_set), i)
    dssim = per_map[per_map.metric == "dssim_I_R"].set_index(["model", "object", "map"])["value"]
    fig, axes = plt.subplots(len(shown), 5, figsize=(8.0, 1.75 * len(shown)), squeeze=False)
    for row, ((name, map_set), i) in zip(axes, shown.items(), strict=True):
        map_name = labels[i][2]
        ndr_error = (reinhard(methods["ndr"]["I_R"][i]) - reinhard(truth["I_R"][i])).abs()
        panels = [
            (f"{name}: albedo A_D", buffers["A_D"][i].permute(1, 2, 0).numpy(), None),
            (f"Mitsuba, {map_set}\n{map_name}", _show(truth["I_R"][i]), None),
            (f"NDR ({dssim[('ndr', name, map_name)]:.3f})", _show(methods["ndr"]["I_R"][i]), None),
            (
                f"shading input ({dssim[(SHADING_INPUT, name, map_name)]:.3f})",
                _show(methods[SHADING_INPUT]["I_R"][i]),
                None,
            ),
            ("|NDR - Mitsuba| (0-0.2)", ndr_error.mean(0).numpy(), "magma"),
        ]
        for ax, (title, image, cmap) in zip(row, panels, strict=True):
            if cmap:
                ax.imshow(image, cmap=cmap, vmin=0, vmax=0.2)
            else:
                ax.imshow(np.clip(image, 0, 1))
            ax.set_title(title, fontsize=6)
            ax.axis("off")
    fig.suptitle("Your objects: Mitsuba, NDR and the shading input (DSSIM of I_R)", fontsize=8)
    fig.tight_layout(rect=(0, 0, 1, 1 - 0.3 / fig.get_figheight()))
    save_figure(fig, out)
