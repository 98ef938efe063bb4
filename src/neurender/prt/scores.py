"""Rendered-appearance scores of predicted transfer (paper 4.1, Table 1, Fig. 7).

Every frame is rendered from a fixed camera (:mod:`neurender.prt.render`) with the
ground-truth transfer and with each model's prediction, on the same geometry. Images are
divided by the ground-truth image's maximum (so they lie in [0, 1]) and compared inside
the object's silhouette: SSIM (:mod:`neurender.metrics`) and L2-RGB (mean squared error).
Both images are clamped at 0 first, as a display shows them: band-limited transfer rings
below zero where little light arrives (a fifth of the cloth's glossy pixels on some test
frames), and SSIM's luminance term is meaningless for a negative mean (with only the
prediction clamped, an independent estimate as good as the reference scored 0.90 there).
Coefficient errors: L1 of the transfer, and ``accuracy = 1 - sum |pred - gt| / sum |gt|``
(our reading of the paper's undefined "accuracy": one minus the relative L1 error).
Radiance error: ``rel_l1_radiance = sum |R_pred - R_gt| / sum |R_gt|`` of the
rendered radiance images inside the silhouette (:func:`relative_l1`), unnormalised.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import torch

from neurender import metrics
from neurender.prt import MATERIALS, render
from neurender.prt.frames import Split
from neurender.tables import tidy_rows

#: ``(model, material) -> (F, C, n, n)`` predicted transfer of every frame of a split.
Predictions = dict[tuple[str, str], np.ndarray]


def radiance(
    material: str,
    coeffs: np.ndarray,
    positions: np.ndarray,
    light: np.ndarray,
    eye: np.ndarray,
    exponent: float,
) -> np.ndarray:
    """Per-vertex radiance ``(n*n, 3)`` of one frame's coefficients ``(C, n, n)`` on its
    geometry image ``(n, n, 3)``, lit by SH ``light`` ``(K, 3)``, seen from ``eye``."""
    n = positions.shape[0]
    c = np.moveaxis(coeffs, 0, -1)
    if material == "diffuse":
        return render.diffuse_radiance(c.reshape(n * n, -1), light)
    return render.glossy_radiance(c.reshape(n, n, 3, -1), positions, eye, exponent)


def displayed(image: np.ndarray, scale: float) -> torch.Tensor:
    """A radiance image ``(C, H, W)`` as shown and scored: divided by ``scale`` (the
    reference's maximum) and clamped at 0, ``(1, C, H, W)`` float64."""
    return torch.from_numpy(np.ascontiguousarray(image[None] / scale)).double().clamp(0, None)


def _tensors(gt: np.ndarray, pred: np.ndarray, mask: np.ndarray) -> tuple[torch.Tensor, ...]:
    """``(1, C, H, W)`` images :func:`displayed` at the ground truth's maximum and the
    ``(1, 1, H, W)`` mask, float64."""
    scale = max(float(gt.max()), 1e-12)
    return displayed(gt, scale), displayed(pred, scale), torch.from_numpy(mask[None]).double()


def image_ssim(gt: np.ndarray, pred: np.ndarray, mask: np.ndarray) -> float:
    """The SSIM of :func:`compare_images` alone (one SSIM evaluation, no maps)."""
    return float(metrics.ssim(*_tensors(gt, pred, mask)))


def relative_l1(pred: np.ndarray, gt: np.ndarray, mask: np.ndarray | None = None) -> float:
    """``sum |pred - gt| / sum |gt|`` over the entries where ``mask`` (broadcast against
    them; ``None``: all) is non-zero, e.g. radiance images ``(3, H, W)`` with a mask
    ``(1, H, W)`` or per-vertex radiance ``(V, 3)``; scale-free, so any units."""
    inside = np.ones(gt.shape, bool) if mask is None else np.broadcast_to(mask != 0, gt.shape)
    denominator = float(np.abs(gt[inside]).sum())
    if denominator <= 0:
        raise ValueError("relative L1: the reference is zero everywhere inside the mask")
    return float(np.abs(pred[inside] - gt[inside]).sum()) / denominator


def compare_images(gt: np.ndarray, pred: np.ndarray, mask: np.ndarray) -> dict[str, np.ndarray]:
    """SSIM and L2-RGB of two ``(3, H, W)`` radiance images inside ``mask`` ``(1, H, W)``.

    Both are divided by the ground truth's maximum and clamped at 0 (:func:`displayed`).
    Returns the scores and the SSIM and L1 maps ``(H, W)`` (for Fig. 7).
    """
    a, b, m = _tensors(gt, pred, mask)
    ssim_map = metrics.ssim_map(a, b)
    return {
        "ssim": float(metrics.ssim(a, b, m)),
        "l2rgb": float(metrics.l2(a, b, m)),
        "ssim_map": (ssim_map.mean(1)[0] * m[0, 0]).numpy(),
        "l1_map": ((a - b).abs().mean(1)[0] * m[0, 0]).numpy(),
    }


def diffuse_ssim(
    positions: np.ndarray, diffuse: np.ndarray, reference: np.ndarray, resolution: int, light
) -> float:
    """Diffuse-render SSIM of a transfer ``(n, n, K)`` against the reference ``(n, n, K)``."""
    raster = render.Raster(positions, resolution)
    n = positions.shape[0]
    gt = raster.shade(render.diffuse_radiance(reference.reshape(n * n, -1), light))
    img = raster.shade(render.diffuse_radiance(diffuse.reshape(n * n, -1), light))
    return compare_images(gt, img, raster.mask_image())["ssim"]


def score_frames(
    name: str,
    split: str,
    data: Split,
    predictions: Predictions,
    extrapolated: np.ndarray,
    light: np.ndarray,
    cfg: dict,
) -> tuple[list[dict], dict]:
    """Tidy rows (one per frame, model and metric) of every prediction of one split.

    Args:
        extrapolated: ``(F,)`` bool, frames outside the training range of shapes.
        cfg: ``render_resolution`` and ``glossy_exponent``.

    Returns:
        the rows and, for Fig. 7, ``(model, material) -> (gt image, image, scores, mask)``
        of the first extrapolated frame (empty unless ``split`` is ``test``).
    """
    rows, panels = [], {}
    shown = int(np.argmax(extrapolated)) if split == "test" else -1
    for f in range(len(data.positions)):
        raster = render.Raster(data.positions[f], cfg["render_resolution"], data.positions)
        mask = raster.mask_image()

        def shade(material, coeffs, f=f, raster=raster):
            return raster.shade(
                radiance(
                    material, coeffs, data.positions[f], light, raster.eye, cfg["glossy_exponent"]
                )
            )

        for material in MATERIALS:
            gt_coeffs = data.targets(material)[f]
            gt_img = shade(material, gt_coeffs)
            for (model, mat), pred in predictions.items():
                if mat != material:
                    continue
                img = shade(material, pred[f])
                scores = compare_images(gt_img, img, mask)
                error = np.abs(pred[f] - gt_coeffs)
                values = {
                    f"ssim_{material}": scores["ssim"],
                    f"l2rgb_{material}": scores["l2rgb"],
                    f"rel_l1_radiance_{material}": relative_l1(img, gt_img, mask),
                    f"l1_{material}": float(error.mean()),
                    f"accuracy_{material}": 1.0 - float(error.sum() / np.abs(gt_coeffs).sum()),
                }
                rows += tidy_rows(
                    "prt", name, model, split, values, frame=f, extrapolated=bool(extrapolated[f])
                )
                if f == shown:
                    panels[(model, material)] = (gt_img, img, scores, mask)
    return rows, panels


def aggregate(frames: pd.DataFrame) -> pd.DataFrame:
    """Mean per (dataset, model, split, metric), the extrapolated test subset, and worst SSIM."""
    keys = ["method", "dataset", "model", "split", "metric"]
    parts = [frames.groupby(keys, as_index=False)["value"].mean()]
    extra = frames[frames["extrapolated"]].assign(split="test (extrapolated)")
    if len(extra):
        parts.append(extra.groupby(keys, as_index=False)["value"].mean())
    worst = frames[frames["metric"].str.startswith("ssim")]
    worst = worst.groupby(keys, as_index=False)["value"].min()
    parts.append(worst.assign(metric=worst["metric"] + "_worst"))
    return pd.concat(parts, ignore_index=True)
