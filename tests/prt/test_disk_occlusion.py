"""The disk-occlusion estimate against an independent quadrature, its invariances, and its
place in the shadowing variant's graph."""

import math

import numpy as np
import pytest
import torch

from neurender import sh
from neurender.prt.disk_occlusion import (
    block_stride,
    occluded_transfer,
    sh_of_monomials,
    vector_area,
    weighted_moments,
)
from neurender.prt.unshadowed import monomial_exponents


def _raw(positions: np.ndarray, normals: np.ndarray) -> torch.Tensor:
    """``(1, 6, n, n)`` float64 from ``(n, n, 3)`` positions and normals."""
    x = np.concatenate([positions, normals], -1)
    return torch.from_numpy(np.moveaxis(x, -1, 0)[None].copy())


def _tube(n: int, radius: float = 1.0, length: float = 4.0):
    """The inside of an open cylinder along z: columns go round, rows along the axis;
    normals point to the axis."""
    theta = 2 * math.pi * np.arange(n) / n
    z = np.linspace(-length / 2, length / 2, n)
    zz, tt = np.meshgrid(z, theta, indexing="ij")
    positions = np.stack([radius * np.cos(tt), radius * np.sin(tt), zz], -1)
    normals = -np.stack([np.cos(tt), np.sin(tt), np.zeros_like(tt)], -1)
    return positions, normals


def test_vector_area_of_a_plane_is_its_area_along_its_normal():
    t = np.linspace(0.0, 3.0, 7)  # spacing 0.5
    yy, xx = np.meshgrid(t, t, indexing="ij")
    p = torch.from_numpy(np.stack([xx, yy, np.zeros_like(xx)])[None])
    a = vector_area(p)[0]
    assert torch.allclose(a[2], torch.full((7, 7), 0.25, dtype=a.dtype))
    assert torch.all(a[:2] == 0)


def _bumps(n: int):
    """A bumpy height field over the unit square and its unit normals, ``(n, n, 3)`` each."""
    t = np.linspace(0.0, 1.0, n)
    yy, xx = np.meshgrid(t, t, indexing="ij")
    z = 0.3 * np.sin(7 * xx) * np.cos(5 * yy)
    dzdx, dzdy = 2.1 * np.cos(7 * xx) * np.cos(5 * yy), -1.5 * np.sin(7 * xx) * np.sin(5 * yy)
    normals = np.stack([-dzdx, -dzdy, np.ones_like(z)], -1)
    return np.stack([xx, yy, z], -1), normals / np.linalg.norm(normals, axis=-1, keepdims=True)


@pytest.mark.parametrize("n_bands", [1, 2, 3, 4, 5])
def test_sh_of_monomials_gives_the_basis_at_unit_vectors(n_bands):
    dirs = np.random.default_rng(3).normal(size=(50, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    exps = monomial_exponents(n_bands - 1)
    powers = np.stack([np.prod(dirs**e, axis=1) for e in exps], 1)
    np.testing.assert_allclose(
        powers @ sh_of_monomials(n_bands), sh.eval_sh(dirs, n_bands), atol=1e-12
    )


def test_weighted_moments_are_the_sums_of_weighted_monomials():
    rng = np.random.default_rng(4)
    weights, x, y, z = (torch.from_numpy(rng.normal(size=(2, 3, 7))) for _ in range(4))
    got = weighted_moments(weights, [x, y, z], 3).numpy()
    for m, (a, b, c) in enumerate(monomial_exponents(3)):
        want = (weights * x**a * y**b * z**c).sum(-1).numpy()
        np.testing.assert_allclose(got[..., m], want, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("glossy", [False, True])
def test_it_is_the_sum_over_element_pairs_of_the_module_docstring(glossy):
    """One-pixel blocks (``grid = n``): every receiver's estimate equals a direct sum over
    the other elements of ``Omega_e max(0, n . w_e) y_k(w_e)`` (diffuse) or ``Omega_e
    [n . w_e > 0] L(w_e) y_k(w_e)`` (glossy), the elements' vector areas from
    :func:`vector_area`."""
    n, n_bands = 6, 3
    positions, normals = _bumps(n)
    light = np.random.default_rng(5).normal(size=(n_bands**2, 3)) if glossy else None
    x = _raw(positions, normals)
    got = occluded_transfer(
        x, n_bands, grid=n, light=None if light is None else torch.from_numpy(light)
    )
    got = got[0].numpy().reshape(-1, n_bands**2, n * n)  # (C, K, R)
    areas = np.moveaxis(vector_area(x[:, :3])[0].numpy(), 0, -1).reshape(-1, 3)
    p, nrm = positions.reshape(-1, 3), normals.reshape(-1, 3)
    for r in range(n * n):
        want = np.zeros((got.shape[0], n_bands**2))
        for e in range(n * n):
            if e == r:
                continue
            v = p[e] - p[r]
            d2 = v @ v
            w = v / math.sqrt(d2)
            omega = 2 * math.pi * (1 - 1 / math.sqrt(1 + abs(areas[e] @ w) / (math.pi * d2)))
            y = sh.eval_sh(w, n_bands)
            if light is None:
                want[0] += omega * max(0.0, nrm[r] @ w) * y
            elif nrm[r] @ w > 0:
                want += omega * np.outer(y @ light, y)
        np.testing.assert_allclose(got[:, :, r], want, rtol=1e-9, atol=1e-12)


def test_a_flat_plane_occludes_nothing():
    t = np.linspace(-1, 1, 16)
    yy, xx = np.meshgrid(t, t, indexing="ij")
    positions = np.stack([xx, yy, 0.2 * xx + 0.1 * yy], -1)  # tilted
    normal = np.array([-0.2, -0.1, 1.0]) / np.linalg.norm([-0.2, -0.1, 1.0])
    x = _raw(positions, np.broadcast_to(normal, positions.shape))
    assert occluded_transfer(x, 4, grid=8).abs().max() < 1e-9


def test_inside_a_tube_it_matches_a_quadrature_of_the_walls():
    """At the middle of the tube's wall (every receiver of a row is the same, by symmetry),
    the estimate's band-0 and band-1 coefficients equal the integral of
    ``max(0, n . w) y_k(w) |n_e . w| / d^2 dA`` over the walls by a fine midpoint rule
    (the small-disk limit of the elements' solid angle)."""
    n = 32
    positions, normals = _tube(n)
    got = occluded_transfer(_raw(positions, normals), 2, grid=n)[0].numpy()  # (4, n, n)
    row = n // 2
    receiver, normal = positions[row, 0], normals[row, 0]
    # The quadrature: 720 x 720 midpoints of the same walls (rows span the same length).
    theta = 2 * math.pi * (np.arange(720) + 0.5) / 720
    span = 4.0 * n / (n - 1)  # the grid's rows are point samples of 4 / (n - 1) each
    z = -span / 2 + span * (np.arange(720) + 0.5) / 720
    zz, tt = np.meshgrid(z, theta, indexing="ij")
    q = np.stack([np.cos(tt), np.sin(tt), zz], -1).reshape(-1, 3)
    qn = -np.stack([np.cos(tt), np.sin(tt), np.zeros_like(tt)], -1).reshape(-1, 3)
    da = (2 * math.pi / 720) * (span / 720)
    v = q - receiver
    d2 = (v * v).sum(1)
    w = v / np.sqrt(d2)[:, None]
    keep = d2 > 1e-6
    weight = np.clip(w @ normal, 0, None) * np.abs((qn * w).sum(1)) / d2 * da
    want = (weight[keep, None] * sh.eval_sh(w[keep], 2)).sum(0)
    # band 0 and the axis-symmetric coefficients; the estimate's pixels are coarse (11°
    # round, 0.13 along), so a few per cent
    np.testing.assert_allclose(got[:, row, 0], want, rtol=0.05, atol=0.02 * abs(want[0]))


def test_invariant_to_translation_and_uniform_scale():
    positions, normals = _tube(16)
    base = occluded_transfer(_raw(positions, normals), 4, grid=8)
    moved = occluded_transfer(_raw(2.5 * positions + [3.0, -1.0, 0.5], normals), 4, grid=8)
    assert torch.allclose(base, moved, atol=1e-10)


def test_a_rotation_about_y_rotates_the_sh_coefficients():
    positions, normals = _tube(16)
    angle = 0.7
    c, s = math.cos(angle), math.sin(angle)
    rot = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    base = occluded_transfer(_raw(positions, normals), 4, grid=8)[0].numpy()
    turned = occluded_transfer(_raw(positions @ rot.T, normals @ rot.T), 4, grid=8)[0].numpy()
    d = sh.rotation_about_y(angle, 4)
    np.testing.assert_allclose(
        np.einsum("kj,jab->kab", d, base), turned, atol=1e-8 * np.abs(base).max() + 1e-12
    )


def test_glossy_under_a_constant_light_scales_with_each_colour():
    """With ``L = c y_0`` the glossy estimate is ``c y_0 sum_e Omega_e [n . w > 0] y_k``:
    its colours in the ratio of ``c``, band 0 positive wherever the walls are seen."""
    positions, normals = _tube(16)
    light = np.zeros((4, 3))
    light[0] = [1.0, 2.0, 3.0]
    out = occluded_transfer(_raw(positions, normals), 2, grid=8, light=torch.from_numpy(light))
    per_colour = out[0].reshape(3, 4, 16, 16)
    assert torch.all(per_colour[0, 0] > 0)
    assert torch.allclose(per_colour[1], 2 * per_colour[0])
    assert torch.allclose(per_colour[2], 3 * per_colour[0])


@pytest.mark.parametrize(
    ("n", "grid", "stride"), [(64, 16, 4), (256, 16, 16), (16, 16, 1), (8, 16, 1), (100, 16, 5)]
)
def test_block_stride_tiles_the_image_in_about_grid_blocks(n, grid, stride):
    assert block_stride(n, grid) == stride
    assert n % stride == 0


def test_an_image_that_no_block_size_divides_still_gets_an_estimate():
    positions, normals = _tube(17)  # prime: one-pixel blocks
    assert occluded_transfer(_raw(positions, normals), 2, grid=4).shape == (1, 4, 17, 17)
