"""Figures of the simplification stage: the held-out comparison, the loss curves and the
meshes in 3D (PyVista)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from neurender.display import srgb
from neurender.plots import plt, save_figure
from neurender.simplification import VARIANTS


def object_crop(alpha: np.ndarray, margin: int = 4) -> tuple[slice, slice]:
    """Rows and columns around the covered pixels of ``alpha (H, W)`` (all if none)."""
    rows, cols = np.nonzero(alpha >= 0.5)
    if len(rows) == 0:
        return slice(None), slice(None)
    h, w = alpha.shape
    return (
        slice(max(rows.min() - margin, 0), min(rows.max() + margin + 1, h)),
        slice(max(cols.min() - margin, 0), min(cols.max() + margin + 1, w)),
    )


def comparison_figure(crops: dict, path: str) -> None:
    """One column triple per case (render, difference x4 with red = too bright and blue =
    too dim, coverage with red = extra and blue = missing), one row per variant under the
    reference row."""
    fig, axes = plt.subplots(
        1 + len(VARIANTS),
        3 * len(crops),
        figsize=(2.2 * 3 * len(crops), 2.3 * (1 + len(VARIANTS))),
        squeeze=False,
    )
    for c, (case, (full_ref, full_images)) in enumerate(crops.items()):
        crop = object_crop(full_ref[..., 3])
        ref = full_ref[crop]
        axes[0, 3 * c].imshow(srgb(ref[..., :3]))
        axes[0, 3 * c].set_title(f"{case}: reference", fontsize=9)
        for k, variant in enumerate(VARIANTS, start=1):
            img = full_images[variant][crop]
            diff = (srgb(img[..., :3]) - srgb(ref[..., :3])).mean(-1)
            signed = np.stack([diff.clip(0), np.zeros_like(diff), (-diff).clip(0)], -1) * 4
            a, r = img[..., 3] >= 0.5, ref[..., 3] >= 0.5
            cover = np.stack([a & ~r, np.zeros_like(a), r & ~a], -1).astype(float)
            cover += 0.25 * (a & r)[..., None]
            panels = (srgb(img[..., :3]), signed.clip(0, 1), cover)
            titles = (f"{case}: {variant}", "difference x4", "coverage")
            for j, (pic, title) in enumerate(zip(panels, titles, strict=True)):
                axes[k, 3 * c + j].imshow(pic)
                axes[k, 3 * c + j].set_title(title, fontsize=9)
    for ax in axes.ravel():
        ax.axis("off")
    fig.tight_layout()
    save_figure(fig, path, dpi=100)


def loss_figure(losses: list[pd.DataFrame], path: str) -> None:
    """Image loss (eq. 4, 25-step running mean) per case over the optimisation."""
    fig, ax = plt.subplots(figsize=(5, 3.2), layout="constrained")
    for loss in losses:
        rows = loss[loss["metric"] == "image_l1"]
        ax.plot(
            rows["step"],
            rows["value"].rolling(25, min_periods=1).mean(),
            label=str(rows["case"].iloc[0]),
        )
    ax.set_xlabel("step")
    ax.set_ylabel("L1 of sRGB(log(x+1))")
    ax.legend()
    save_figure(fig, path)


def meshes_figure(
    case: str,
    reference: tuple[np.ndarray, np.ndarray],
    qem: tuple[np.ndarray, np.ndarray],
    ours: tuple[np.ndarray, np.ndarray],
    path: str,
) -> None:
    """PyVista figure of one case: the detailed reference surface, the QEM mesh (also the
    classic bake's) and ours, each ``(vertices (V, 3), faces (F, 3))`` in the stage's
    frame; the two simplified meshes with their wireframes, ours coloured by each vertex's
    distance from its QEM position (the optimisation's displacement, stage units)."""
    from neurender.mesh_figures import Panel, render_panels

    moved = np.linalg.norm(ours[0] - qem[0], axis=1)
    panels = [
        Panel(*reference, title=f"{case}: reference, {len(reference[1]):,} triangles"),
        Panel(*qem, title=f"QEM (and classic bake), {len(qem[1]):,} triangles", edges=True),
        Panel(
            *ours,
            title=f"ours, {len(ours[1]):,} triangles",
            edges=True,
            scalars=moved,
            clim=(0.0, max(float(moved.max()), 1e-9)),
            scalar_title="moved from QEM",
        ),
    ]
    render_panels(panels, path, (1, 3), (1100, 400))
