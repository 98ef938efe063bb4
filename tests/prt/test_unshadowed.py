import math

import numpy as np
import pytest
import torch

from neurender import sh
from neurender.geometry import grid_faces
from neurender.prt import transfer, unshadowed


def _unit(rng, count):
    n = rng.normal(size=(count, 3))
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def _latlong(height=600):
    dirs, solid_angle = sh.latlong_directions(height, 2 * height)
    return dirs.reshape(-1, 3), solid_angle.reshape(-1)


def test_band_scale_is_the_clamped_cosine_lobe():
    assert np.allclose(
        unshadowed.band_scale(4)[[0, 1, 4, 9]], [math.pi, 2 * math.pi / 3, math.pi / 4, 0]
    )


@pytest.mark.parametrize("n_bands", [1, 2, 4, 5])
def test_diffuse_matches_brute_force_quadrature(n_bands):
    """t_j = integral max(n.w, 0) y_j(w) dw by midpoint quadrature on a fine lat-long grid."""
    dirs, solid_angle = _latlong()
    y = sh.eval_sh(dirs, n_bands)
    for n in _unit(np.random.default_rng(0), 4):
        weight = np.clip(dirs @ n, 0, None) * solid_angle
        assert np.allclose(weight @ y, unshadowed.diffuse(n, n_bands), atol=2e-5)


def test_diffuse_torch_equals_numpy():
    n = _unit(np.random.default_rng(1), 10)
    got = unshadowed.diffuse(torch.from_numpy(n), 4).numpy()
    assert np.allclose(got, unshadowed.diffuse(n, 4), atol=1e-12)


def test_glossy_exact_matches_brute_force_quadrature():
    """R_i = integral_{n.w > 0} y_i L dw on a fine lat-long grid."""
    rng = np.random.default_rng(2)
    light = rng.normal(size=(16, 3))
    dirs, solid_angle = _latlong()
    y = sh.eval_sh(dirs, 4)
    radiance = y @ light
    normals = _unit(rng, 3)
    exact = unshadowed.glossy_exact(normals, light)
    for n, want in zip(normals, exact, strict=True):
        upper = (dirs @ n > 0) * solid_angle
        brute = np.einsum("s,sc,sk->ck", upper, radiance, y)
        assert np.abs(brute - want).max() < 3e-3 * np.abs(want).max()


@pytest.mark.parametrize("n_bands", [2, 3, 4])
def test_glossy_polynomial_reproduces_the_exact_quadrature(n_bands):
    rng = np.random.default_rng(3)
    light = rng.normal(size=(n_bands**2, 3))
    coeffs = unshadowed.glossy_polynomial(light)
    normals = _unit(rng, 50)
    want = unshadowed.glossy_exact(normals, light).reshape(50, -1)
    assert np.allclose(unshadowed.glossy(normals, coeffs), want, atol=1e-9)
    got = unshadowed.glossy(torch.from_numpy(normals), torch.from_numpy(coeffs)).numpy()
    assert np.allclose(got, want, atol=1e-9)


def test_glossy_of_a_constant_light_is_the_hemisphere_integral():
    """L = c y_00 (constant c / sqrt(4 pi)): R_00 = 2 pi c / (4 pi) = c / 2 for any normal."""
    light = np.zeros((16, 3))
    light[0] = [1.0, 2.0, 3.0]
    normals = _unit(np.random.default_rng(4), 5)
    got = unshadowed.glossy_exact(normals, light)
    assert np.allclose(got[:, :, 0], 0.5 * light[0], atol=1e-12)


def test_pipeline_transfer_of_an_unoccluded_plane_is_unshadowed():
    """The ray-traced transfer of a flat sheet (nothing above its tangent plane) equals the
    analytic unshadowed transfer up to Monte Carlo noise, averaged over its vertices."""
    n = 12
    t = np.linspace(-1.0, 1.0, n)
    yy, xx = np.meshgrid(t, t, indexing="ij")
    positions = np.stack([xx, yy, np.zeros_like(xx)], -1)
    light = np.random.default_rng(5).normal(size=(16, 3))
    sets = transfer.DirectionSets(8, 1024, 4, np.random.default_rng(6))
    normals, diffuse, glossy, _ = transfer.frame_transfer(
        positions, grid_faces(n), sets, np.random.default_rng(7), 1e-3, light
    )
    assert np.allclose(normals, [0, 0, 1], atol=1e-6)
    want_d = unshadowed.diffuse(np.array([0.0, 0.0, 1.0]), 4)
    want_g = unshadowed.glossy_exact(np.array([[0.0, 0.0, 1.0]]), light)[0]
    # Per vertex within the noise of 1024 stratified samples; the mean over 8 direction
    # sets within that noise over sqrt(8) (a wrong A_l would be off by 0.1 or more).
    assert np.abs(diffuse - want_d).max() < 0.02
    assert np.abs(diffuse.mean((0, 1)) - want_d).max() < 6e-3
    assert np.abs(glossy.mean((0, 1)) - want_g).max() < 0.02 * np.abs(want_g).max()


@pytest.mark.parametrize("library", ["numpy", "torch"])
def test_channels_first_images_give_the_per_pixel_transfer(library):
    """``axis=1`` on normal images ``(B, 3, H, W)``: every pixel's diffuse and glossy
    transfer as the default layout gives it, along the channel axis."""
    rng = np.random.default_rng(4)
    normals = _unit(rng, 2 * 5 * 6).reshape(2, 5, 6, 3)
    coeffs = unshadowed.glossy_polynomial(rng.normal(size=(16, 3)))
    images = np.ascontiguousarray(normals.transpose(0, 3, 1, 2))
    if library == "torch":
        normals, images, coeffs = (torch.from_numpy(a) for a in (normals, images, coeffs))
    for per_pixel, channels_first in (
        (unshadowed.diffuse(normals, 4), unshadowed.diffuse(images, 4, axis=1)),
        (unshadowed.glossy(normals, coeffs), unshadowed.glossy(images, coeffs, axis=1)),
    ):
        expected = np.asarray(per_pixel).transpose(0, 3, 1, 2)
        np.testing.assert_allclose(np.asarray(channels_first), expected, atol=1e-12)


def test_monomial_parent_is_one_power_less_along_its_axis():
    for e in unshadowed.monomial_exponents(4)[1:]:
        parent, axis = unshadowed.monomial_parent(e)
        assert parent in unshadowed.monomial_exponents(sum(e) - 1)
        assert e[axis] == parent[axis] + 1
        assert all(e[k] == parent[k] for k in range(3) if k != axis)
