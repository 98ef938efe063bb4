"""Paper section 4.2.2 (Fig. 6) and Fig. 2: DeepPRT along a path of shapes, and under a
blend of two light probes, scored against the ground truth by diffuse renders
(:func:`neurender.prt.scores.compare_images`)."""

from __future__ import annotations

import numpy as np

from neurender.prt import render
from neurender.prt.frames import Split
from neurender.prt.scores import compare_images
from neurender.tables import tidy_rows


def path_coordinate(name: str, data: Split) -> tuple[np.ndarray, str]:
    """The path coordinate ``x`` ``(F,)`` of an experiment's test frames and its label:
    ``a`` of the linear shape space (``head_linear``) or the distance ``t`` from the mean
    training shape to the excluded expression (``head_excluded``)."""
    if name == "head_linear":
        return data.params[:, 0], "a in S_lin = a S_head + (1 - a) S_plane"
    return (
        np.linspace(0.0, 1.0, len(data.positions)),
        "t: mean shape (0) to excluded expression (1)",
    )


def path_rows(
    name: str,
    data: Split,
    x: np.ndarray,
    predictions: dict[str, np.ndarray],
    light: np.ndarray,
    resolution: int,
) -> list[dict]:
    """Diffuse L2-RGB and SSIM of each model's predictions ``(F, K, n, n)`` at every test
    frame, one tidy row per frame (keyed by ``x``) and metric."""
    rows = []
    n = data.positions.shape[1]
    for f in range(len(data.positions)):
        raster = render.Raster(data.positions[f], resolution, data.positions)
        gt = raster.shade(render.diffuse_radiance(data.diffuse[f].reshape(n * n, -1), light))
        for model, pred in predictions.items():
            img = raster.shade(
                render.diffuse_radiance(np.moveaxis(pred[f], 0, -1).reshape(n * n, -1), light)
            )
            scores = compare_images(gt, img, raster.mask_image())
            values = {f"{metric}_diffuse": scores[metric] for metric in ("l2rgb", "ssim")}
            rows += tidy_rows("prt", name, model, "test", values, x=round(float(x[f]), 4))
    return rows


def relight_rows(
    name: str,
    data: Split,
    prediction: np.ndarray,
    probes: list[np.ndarray],
    resolution: int,
    steps: int = 5,
) -> tuple[list[dict], list[tuple[float, np.ndarray, np.ndarray, float]]]:
    """Test frame 0 relit while the light blends from the first probe to the second.

    SH lighting is linear, so the blend of two probes is the blend of their coefficients
    ``(K, 3)``; the transfer (ground truth, or DeepPRT's ``prediction (K, n, n)``) is
    computed once.

    Returns:
        tidy SSIM rows per blend weight, and ``(weight, ground-truth image, prediction
        image, SSIM)`` per weight for the figure.
    """
    n = data.positions.shape[1]
    raster = render.Raster(data.positions[0], resolution)
    gt_t = data.diffuse[0].reshape(n * n, -1)
    pred_t = np.moveaxis(prediction, 0, -1).reshape(n * n, -1)
    rows, blends = [], []
    for w in np.linspace(0.0, 1.0, steps):
        light = (1 - w) * probes[0] + w * probes[1]
        gt = raster.shade(render.diffuse_radiance(gt_t, light))
        img = raster.shade(render.diffuse_radiance(pred_t, light))
        ssim = compare_images(gt, img, raster.mask_image())["ssim"]
        rows += tidy_rows(
            "prt", name, "DeepPRT", "test", {"ssim_diffuse": ssim}, blend=round(float(w), 3)
        )
        blends.append((float(w), gt, img, ssim))
    return rows, blends
