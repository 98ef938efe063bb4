import math

import numpy as np
import pytest
import scipy.special
import torch

from neurender import sh


def _scipy_real_sh(dirs: np.ndarray, n_bands: int) -> np.ndarray:
    """Real SH with the Condon-Shortley phase, built from scipy's complex SH."""
    theta = np.arccos(np.clip(dirs[:, 2], -1, 1))
    phi = np.arctan2(dirs[:, 1], dirs[:, 0])
    out = np.zeros((len(dirs), n_bands**2))
    for l in range(n_bands):  # noqa: E741
        for m in range(-l, l + 1):
            y = scipy.special.sph_harm_y(l, abs(m), theta, phi)
            if m > 0:
                v = math.sqrt(2) * y.real
            elif m < 0:
                v = math.sqrt(2) * y.imag
            else:
                v = y.real
            out[:, sh.sh_index(l, m)] = v
    return out


def test_matches_scipy_to_1e6():
    rng = np.random.default_rng(0)
    d = rng.normal(size=(500, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    np.testing.assert_allclose(sh.eval_sh(d, 5), _scipy_real_sh(d, 5), atol=1e-6)


def test_sloan_signs():
    # Sloan's table: y_1^-1 = -c y, y_1^0 = c z, y_1^1 = -c x
    c = 0.488602511902920
    y = sh.eval_sh(np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]), 2)
    np.testing.assert_allclose(y[0, 1:], [0, 0, -c], atol=1e-12)
    np.testing.assert_allclose(y[1, 1:], [-c, 0, 0], atol=1e-12)
    np.testing.assert_allclose(y[2, 1:], [0, c, 0], atol=1e-12)


def test_orthonormal_by_quadrature():
    dirs, dw = sh.latlong_directions(256, 512)
    y = sh.eval_sh(dirs, 5).reshape(-1, 25)
    gram = (y * dw.reshape(-1, 1)).T @ y
    np.testing.assert_allclose(gram, np.eye(25), atol=2e-4)


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_torch_matches_numpy(dtype):
    rng = np.random.default_rng(1)
    d = rng.normal(size=(64, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    out = sh.eval_sh(torch.tensor(d, dtype=dtype), 5)
    assert out.dtype == dtype and out.shape == (64, 25)
    np.testing.assert_allclose(out.double().numpy(), sh.eval_sh(d, 5), atol=1e-5)


def test_clamped_cosine_zonal_coefficients():
    dirs, dw = sh.latlong_directions(512, 1024)
    # a cosine lobe around +z, projected numerically
    f = np.clip(dirs[..., 2], 0, None)
    y = sh.eval_sh(dirs, 5)
    coeffs = np.einsum("hw,hwk->k", f * dw, y)
    expected = [0.886227, 1.023327, 0.495416, 0.0, -0.110778]
    zonal = [coeffs[sh.sh_index(l, 0)] for l in range(5)]  # noqa: E741
    np.testing.assert_allclose(zonal, expected, atol=2e-4)
    np.testing.assert_allclose(sh.CLAMPED_COSINE_ZONAL, expected, atol=1e-6)
    # the non-zonal coefficients of a z-symmetric lobe vanish
    nonzonal = np.delete(coeffs, [sh.sh_index(l, 0) for l in range(5)])  # noqa: E741
    assert np.abs(nonzonal).max() < 1e-5


def test_rotate_zonal_matches_projection():
    axis = np.array([0.3, -0.5, 0.8])
    axis /= np.linalg.norm(axis)
    dirs, dw = sh.latlong_directions(512, 1024)
    f = np.clip(dirs @ axis, 0, None)
    numeric = np.einsum("hw,hwk->k", f * dw, sh.eval_sh(dirs, 5))
    np.testing.assert_allclose(
        sh.rotate_zonal(np.array(sh.CLAMPED_COSINE_ZONAL), axis), numeric, atol=5e-4
    )


def test_latlong_round_trip_of_band_limited_function():
    rng = np.random.default_rng(2)
    coeffs = rng.normal(size=(16, 3))
    image = sh.reconstruct_latlong(coeffs, 128, 256)
    np.testing.assert_allclose(sh.project_latlong(image, 4), coeffs, atol=2e-3)
    assert sh.project_latlong(image[..., 0], 4).shape == (16,)


def test_latlong_convention_matches_mitsuba():
    dirs, dw = sh.latlong_directions(8, 16)
    np.testing.assert_allclose(dw.sum(), 4 * np.pi, rtol=2e-2)
    # u = atan2(x, -z) / 2 pi, v = acos(y) / pi at pixel centres
    u = np.mod(np.arctan2(dirs[..., 0], -dirs[..., 2]) / (2 * np.pi), 1.0)
    v = np.arccos(dirs[..., 1]) / np.pi
    np.testing.assert_allclose(u * 16 - 0.5, np.broadcast_to(np.arange(16), (8, 16)), atol=1e-9)
    np.testing.assert_allclose(
        v * 8 - 0.5, np.broadcast_to(np.arange(8)[:, None], (8, 16)), atol=1e-9
    )


def test_stratified_directions_are_unit_and_stratified():
    rng = np.random.default_rng(3)
    d = sh.stratified_sphere_directions(256, rng)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-12)
    # exactly n/side samples fall in each z stratum
    strata = np.floor((1 - d[:, 2]) / 2 * 16).astype(int)
    assert np.bincount(strata, minlength=16).tolist() == [16] * 16
    # integrates the zonal cosine projection far better than its variance would allow
    y = sh.eval_sh(d, 1)[:, 0]
    assert abs((4 * np.pi / 256) * (np.clip(d[:, 2], 0, None) * y).sum() - 0.886227) < 0.01


def test_bad_inputs_raise():
    with pytest.raises(ValueError, match="perfect square"):
        sh.stratified_sphere_directions(300, np.random.default_rng(0))
    with pytest.raises(ValueError, match="n_bands"):
        sh.eval_sh(np.zeros((1, 3)), 6)


@pytest.mark.parametrize("angle", [0.0, 0.3, math.pi / 2, 2.0])
def test_rotation_about_y_is_orthogonal_and_turns_a_probe(angle):
    rot = sh.rotation_about_y(angle, 4)
    np.testing.assert_allclose(rot @ rot.T, np.eye(16), atol=1e-12)
    # A band-limited function turned about +y by a whole number of lat-long columns: the
    # rotated coefficients equal the projection of the rolled map (a right-handed turn
    # about +y takes -z towards -x, i.e. to smaller u: rolling by +shift turns by -angle).
    h, w = 64, 128
    coeffs = np.random.default_rng(4).normal(size=(16, 3))
    image = sh.reconstruct_latlong(coeffs, h, w)
    shift = round(angle / (2 * math.pi) * w)
    turned = sh.project_latlong(np.roll(image, shift, axis=1), 4)
    np.testing.assert_allclose(
        sh.rotation_about_y(-2 * math.pi * shift / w, 4) @ coeffs, turned, atol=2e-3
    )


def test_rotation_about_y_keeps_the_constant_and_composes():
    a, b = sh.rotation_about_y(0.4, 3), sh.rotation_about_y(0.7, 3)
    np.testing.assert_allclose(a @ b, sh.rotation_about_y(1.1, 3), atol=1e-12)
    np.testing.assert_allclose(a[0], np.eye(9)[0], atol=1e-12)


@pytest.mark.parametrize("library", ["numpy", "torch"])
def test_eval_sh_along_another_axis_is_the_transposed_basis(library):
    """Components along ``axis=-2`` (channels first) give the basis along that axis: the
    same values as the default layout, transposed."""
    dirs = sh.stratified_sphere_directions(36, np.random.default_rng(2)).reshape(2, 18, 3)
    channels_first = np.swapaxes(dirs, -1, -2)
    if library == "torch":
        dirs, channels_first = torch.from_numpy(dirs), torch.from_numpy(channels_first.copy())
    expected = np.swapaxes(np.asarray(sh.eval_sh(dirs, 5)), -1, -2)
    got = np.asarray(sh.eval_sh(channels_first, 5, axis=-2))
    assert got.shape == (2, 25, 18)
    np.testing.assert_allclose(got, expected, atol=1e-15)
