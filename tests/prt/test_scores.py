"""Rendered-appearance scores: the relative L1 of radiance against analytic values, SSIM of
the displayed (clamped) images."""

import numpy as np
import pandas as pd
import pytest

from neurender.prt.frames import Split
from neurender.prt.geometry_image import grid_uv
from neurender.prt.scores import compare_images, image_ssim, relative_l1, score_frames


def test_relative_l1_of_a_uniform_scaling_is_the_scale_error():
    gt = np.random.default_rng(0).uniform(0.1, 2.0, (3, 5, 7))
    assert relative_l1(1.2 * gt, gt) == pytest.approx(0.2)
    assert relative_l1(gt, gt) == 0.0


def test_relative_l1_counts_only_the_pixels_inside_the_mask():
    gt = np.ones((3, 2, 2))
    pred = gt.copy()
    pred[:, 0, 0] = 3.0  # |error| 2 on one pixel of three channels
    pred[:, 1, 1] = 100.0  # outside the mask: ignored
    mask = np.array([[[1.0, 1.0], [1.0, 0.0]]])
    # inside: 3 pixels x 3 channels of |gt| = 1, error 2 on 3 entries: 6 / 9
    assert relative_l1(pred, gt, mask) == pytest.approx(6 / 9)


def test_relative_l1_of_a_zero_reference_is_refused():
    with pytest.raises(ValueError, match="zero everywhere inside the mask"):
        relative_l1(np.ones((3, 2, 2)), np.zeros((3, 2, 2)))


def test_every_frame_scores_its_radiance_error_per_material():
    """Coefficients 10 % too large render radiance 10 % too large (rendering is linear in
    them): rel_l1_radiance 0.1 for both materials, 0 for the ground truth itself."""
    n, k = 8, 16
    uv = grid_uv(n)
    square = np.column_stack([2 * uv - 1, 0.1 * uv[:, 0]]).reshape(n, n, 3)
    rng = np.random.default_rng(1)
    diffuse = rng.uniform(0.1, 1.0, (2, n, n, k)).astype(np.float32)
    glossy = rng.uniform(0.1, 1.0, (2, n, n, 3, k)).astype(np.float32)
    positions = np.stack([square, square]).astype(np.float32)
    normals = np.broadcast_to(np.array([0, 0, 1], np.float32), positions.shape).copy()
    data = Split(positions, normals, diffuse, glossy, np.zeros((2, 1), np.float32))
    preds = {}
    for material in ("diffuse", "glossy"):
        preds["exact", material] = data.targets(material)
        preds["scaled", material] = 1.1 * data.targets(material)
    light = rng.uniform(0.1, 1.0, (k, 3))
    cfg = {"render_resolution": 24, "glossy_exponent": 16.0}
    rows, _ = score_frames("obj", "val", data, preds, np.zeros(2, bool), light, cfg)
    table = pd.DataFrame(rows)
    for material in ("diffuse", "glossy"):
        sel = table[table.metric == f"rel_l1_radiance_{material}"].set_index(["model", "frame"])
        assert len(sel) == 4
        np.testing.assert_allclose(sel.loc["scaled"].value, 0.1, rtol=1e-5)
        np.testing.assert_allclose(sel.loc["exact"].value, 0.0, atol=1e-7)


def test_an_exact_prediction_scores_ssim_one_where_the_reference_rings_below_zero():
    """Band-limited radiance is negative in places; a prediction equal to the reference
    must still score 1 (both are compared as displayed, clamped at 0)."""
    rng = np.random.default_rng(2)
    gt = rng.uniform(-0.2, 1.0, (3, 16, 16))
    gt[:, :6] = rng.uniform(-0.2, -0.01, (3, 6, 16))  # a dark band entirely below zero
    mask = np.ones((1, 16, 16))
    assert image_ssim(gt, gt.copy(), mask) == pytest.approx(1.0, abs=1e-5)
    assert compare_images(gt, gt.copy(), mask)["l2rgb"] == 0.0


def test_ssim_compares_the_images_as_displayed():
    """Two images that differ only below zero look the same (SSIM 1); one that differs
    above zero does not."""
    rng = np.random.default_rng(3)
    gt = rng.uniform(0.1, 1.0, (3, 16, 16))
    gt[:, :4] = -0.1
    mask = np.ones((1, 16, 16))
    darker = gt.copy()
    darker[:, :4] = -0.5
    assert image_ssim(gt, darker, mask) == pytest.approx(1.0, abs=1e-5)
    brighter = gt.copy()
    brighter[:, :4] = 0.3
    assert image_ssim(gt, brighter, mask) < 0.99
