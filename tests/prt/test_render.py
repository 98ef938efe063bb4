import math

import numpy as np
import pytest

from neurender.prt import render, scores
from neurender.prt.geometry_image import grid_uv


@pytest.mark.parametrize("exponent", [1.0, 16.0, 64.0])
def test_normalised_phong_lobe_has_unit_integral(exponent):
    g = render.phong_zonal(exponent, 4)
    # g_0 = integral(lobe) * y_0 = y_0 for a normalised lobe
    assert g[0] == pytest.approx(0.5 / math.sqrt(math.pi), rel=1e-4)
    # convolution weight of band 1 of a normalised Phong lobe: (s + 1) / (s + 2)
    assert math.sqrt(4 * math.pi / 3) * g[1] == pytest.approx(
        (exponent + 1) / (exponent + 2), rel=1e-3
    )


def _square(n=8):
    uv = grid_uv(n)
    return np.column_stack([2 * uv - 1, np.zeros(len(uv))]).reshape(n, n, 3)


def test_raster_of_a_square_shades_constant_values():
    raster = render.Raster(_square(), 32)
    assert 0.1 < raster.mask.mean() < 0.9
    img = raster.shade(np.full((64, 2), 3.0, np.float32))
    assert img.shape == (2, 32, 32)
    np.testing.assert_allclose(img[:, raster.mask.reshape(32, 32)], 3.0, rtol=1e-5)
    assert (img[:, ~raster.mask.reshape(32, 32)] == 0).all()


def test_diffuse_radiance_of_constant_light_is_albedo_times_unoccluded_cosine():
    t = np.zeros((1, 16))
    t[0, 0] = 0.886227  # unoccluded clamped cosine
    light = np.zeros((16, 3))
    light[0] = math.sqrt(4 * math.pi)
    np.testing.assert_allclose(render.diffuse_radiance(t, light), 1.0, rtol=1e-5)


def test_compare_images_identity_and_error():
    rng = np.random.default_rng(0)
    gt = rng.uniform(0.2, 1.0, (3, 24, 24))
    mask = np.ones((1, 24, 24), np.float32)
    same = scores.compare_images(gt, gt, mask)
    assert same["ssim"] == pytest.approx(1.0) and same["l2rgb"] == 0.0
    worse = scores.compare_images(gt, gt * 0.5, mask)
    assert worse["l2rgb"] > 0 and worse["ssim"] < 1.0
