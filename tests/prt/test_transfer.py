import math

import numpy as np

from neurender import sh
from neurender.geometry import grid_faces
from neurender.prt import transfer


def _hits_any(tris, origin, dirs):
    """Brute-force Moeller-Trumbore: does each ray (origin, dirs (R, 3)) hit any triangle?"""
    e1, e2 = tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
    p = np.cross(dirs[:, None], e2[None])
    det = np.einsum("rtc,tc->rt", p, e1)
    inv = 1.0 / np.where(np.abs(det) < 1e-12, np.nan, det)
    s = origin - tris[:, 0]
    u = np.einsum("rtc,tc->rt", p, s) * inv
    q = np.cross(s, e1)
    v = np.einsum("rc,tc->rt", dirs, q) * inv
    t = np.einsum("tc,tc->t", e2, q) * inv
    return ((u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)).any(axis=1)


def _sheet(n=9, size=4.0):
    t = np.linspace(-size / 2, size / 2, n)
    y, x = np.meshgrid(t, t, indexing="ij")
    return np.stack([x, y, np.zeros_like(x)], -1)


def _well(n=17, depth=1.5):
    """A sheet with a deep Gaussian pit at its centre (a concavity)."""
    p = _sheet(n, 4.0)
    r2 = p[..., 0] ** 2 + p[..., 1] ** 2
    p[..., 2] = -depth * np.exp(-r2 / 0.3)
    return p


def _transfer(positions, directions, seed=0, light=None, sets=8):
    rng = np.random.default_rng(seed)
    ds = transfer.DirectionSets(sets, directions, 4, rng)
    return transfer.frame_transfer(
        positions, grid_faces(positions.shape[0]), ds, rng, 1e-3, light, threads=2
    )


def test_unoccluded_vertex_gives_clamped_cosine_zonal_values():
    _, diffuse, _, _ = _transfer(_sheet(), 1024)
    expected = np.zeros(16)
    for l in range(4):  # noqa: E741
        expected[sh.sh_index(l, 0)] = sh.CLAMPED_COSINE_ZONAL[l]
    centre = diffuse[4, 4]
    np.testing.assert_allclose(centre, expected, atol=0.02)


def test_concavity_has_less_ambient_transfer():
    _, flat, _, _ = _transfer(_sheet(17), 256)
    _, well, _, _ = _transfer(_well(), 256)
    assert well[8, 8, 0] < 0.6 * flat[8, 8, 0]


def test_error_shrinks_at_least_like_inverse_sqrt():
    expected = sh.CLAMPED_COSINE_ZONAL[0]
    err = {}
    for count in (64, 1024):
        errors = [_transfer(_sheet(), count, seed=s)[1][2:7, 2:7, 0] - expected for s in range(4)]
        err[count] = np.sqrt(np.mean(np.square(errors)))
    assert err[1024] < err[64] / 4 * 1.25


def test_constant_environment_relighting_equals_cosine_weighted_ambient_occlusion():
    positions = _well(n=13)
    light = np.zeros((16, 3))
    light[0] = math.sqrt(4 * math.pi)  # constant unit radiance
    normals, diffuse, glossy, _ = _transfer(positions, 1024, light=light)
    relit = transfer.relight_diffuse(diffuse, light)
    # White furnace: an unoccluded corner of the sheet reflects exactly 1.
    np.testing.assert_allclose(relit[0, 6], 1.0, atol=0.03)
    # Independent estimate with a brute-force Moeller-Trumbore caster and cosine-weighted sampling.
    tris = positions.reshape(-1, 3)[grid_faces(13)]
    rng = np.random.default_rng(1)
    for i, j in ((6, 6), (6, 4), (4, 6)):
        n = normals[i, j].astype(np.float64)
        u1, u2 = rng.random(4000), rng.random(4000)
        local = np.stack(
            [
                np.sqrt(u1) * np.cos(2 * np.pi * u2),
                np.sqrt(u1) * np.sin(2 * np.pi * u2),
                np.sqrt(1 - u1),
            ],
            1,
        )
        t = np.cross(n, [1.0, 0, 0] if abs(n[0]) < 0.9 else [0, 1.0, 0])
        t /= np.linalg.norm(t)
        dirs = local @ np.stack([t, np.cross(n, t), n])
        origins = np.repeat(positions[i, j][None] + 1e-3 * 4.3 * n, len(dirs), 0)
        visible = ~_hits_any(tris, origins[0], dirs)
        # (1/pi) int V cos dw = E[V] under cosine-weighted sampling
        np.testing.assert_allclose(relit[i, j, 0], visible.mean(), atol=0.04)
    # Glossy radiance of a constant light, R_0 = int V y_0 L dw, shrinks with occlusion.
    assert glossy[0, 6, 0, 0] > glossy[6, 6, 0, 0] > 0
