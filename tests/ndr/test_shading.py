import math

import numpy as np
import pytest
import torch

from neurender import sh
from neurender.ndr.shading import bright_texels, coarse_shading, lookup, smith_g1


def _ggx_albedo_by_quadrature(cos_v: float, alpha: float, n: int = 400) -> float:
    """Independent reference: midpoint quadrature over the hemisphere of
    D(h) G(v, l) / (4 n.v) cos... written out with the half-vector Jacobian folded in."""
    theta = (np.arange(n) + 0.5) / n * math.pi / 2
    phi = (np.arange(2 * n) + 0.5) / (2 * n) * 2 * math.pi
    t, p = np.meshgrid(theta, phi, indexing="ij")
    l_dir = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1)
    v = np.array([math.sqrt(1 - cos_v**2), 0.0, cos_v])
    h = l_dir + v
    h /= np.linalg.norm(h, axis=-1, keepdims=True)
    cos_h = h[..., 2]
    d = alpha**2 / (math.pi * ((alpha**2 - 1) * cos_h**2 + 1) ** 2)
    g = smith_g1(torch.tensor(l_dir[..., 2]), torch.tensor(alpha)).numpy() * float(
        smith_g1(torch.tensor(cos_v), torch.tensor(alpha))
    )
    f = d * g / (4 * cos_v)  # BRDF x cos(l) = D G / (4 cos v cos l) x cos l
    d_omega = np.sin(t) * (math.pi / 2 / n) * (2 * math.pi / (2 * n))
    return float((f * d_omega).sum())


def _points(n: int, normal, view):
    normals = torch.tensor([normal], dtype=torch.float64).expand(n, 3)
    views = torch.tensor([view], dtype=torch.float64)
    views = (views / views.norm(dim=-1, keepdim=True)).expand(n, 3)
    return normals, views


def test_constant_environment_gives_unit_diffuse_shading():
    n = torch.nn.functional.normalize(torch.randn(500, 3, dtype=torch.float64), dim=-1)
    s_d, _ = coarse_shading(
        n, n, torch.full((500,), 0.3), torch.ones(16, 32, 3), 64, torch.Generator().manual_seed(0)
    )
    np.testing.assert_allclose(s_d.numpy(), 1.0, atol=1e-12)


@pytest.mark.parametrize(("cos_v", "alpha"), [(1.0, 0.2), (0.6, 0.5), (0.9, 0.9)])
def test_specular_shading_matches_ggx_albedo_by_quadrature(cos_v, alpha):
    normals, views = _points(2000, (0.0, 0.0, 1.0), (math.sqrt(1 - cos_v**2), 0.0, cos_v))
    _, s_s = coarse_shading(
        normals,
        views,
        torch.full((2000,), alpha),
        torch.ones(16, 32, 3),
        64,
        torch.Generator().manual_seed(1),
    )
    expected = _ggx_albedo_by_quadrature(cos_v, alpha)
    assert float(s_s.mean()) == pytest.approx(expected, rel=0.02)


def test_smooth_specular_reads_the_mirror_direction():
    """Nearly mirror-like GGX sees the map in the reflected direction."""
    env = torch.zeros(16, 32, 3)
    env[5, 9] = torch.tensor([3.0, 2.0, 1.0])
    dirs, _ = sh.latlong_directions(16, 32)
    target = torch.tensor(dirs[5, 9])
    normal = torch.nn.functional.normalize(
        target + torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64), dim=0
    )
    normals, views = _points(64, tuple(normal.tolist()), (0.0, 0.0, 1.0))
    _, s_s = coarse_shading(
        normals, views, torch.full((64,), 1e-3), env.double(), 64, torch.Generator().manual_seed(2)
    )
    np.testing.assert_allclose(s_s.mean(0).numpy(), [3.0, 2.0, 1.0], rtol=0.02)


def test_lookup_follows_the_latlong_convention():
    env = torch.arange(8 * 16 * 3, dtype=torch.float64).reshape(8, 16, 3)
    dirs, _ = sh.latlong_directions(8, 16)
    np.testing.assert_array_equal(lookup(env, torch.tensor(dirs)).numpy(), env.numpy())


def test_sample_count_must_be_square():
    n = torch.tensor([[0.0, 0.0, 1.0]])
    with pytest.raises(ValueError, match="samples=10"):
        coarse_shading(n, n, torch.tensor([0.5]), torch.ones(4, 8, 3), 10, torch.Generator())


# --- bright texels: explicit sampling of a tiny sun, combined by MIS ---

SUN_ROW, SUN_COL = 4, 21  # a texel of a 16 x 32 map, above the horizon


def _sun_map(radiance: float = 2e4) -> torch.Tensor:
    """Black but for one bright texel: the coarse map of a small sun."""
    env = torch.zeros(16, 32, 3, dtype=torch.float64)
    env[SUN_ROW, SUN_COL] = radiance
    return env


def _texel_quadrature(normals: np.ndarray, views: np.ndarray, alpha: float, n: int = 100):
    """Brute force, independent of the estimator: midpoint quadrature over the sun texel
    of ``max(n.l, 0) / pi`` and of the GGX ``f cos`` (per point), unit radiance."""
    h, w = 16, 32
    t = (SUN_ROW + (np.arange(n) + 0.5) / n) * math.pi / h
    p = (SUN_COL + (np.arange(n) + 0.5) / n) * 2 * math.pi / w
    tt, pp = np.meshgrid(t, p, indexing="ij")
    dirs = np.stack([np.sin(tt) * np.sin(pp), np.cos(tt), -np.sin(tt) * np.cos(pp)], -1)
    d_omega = (np.sin(tt) * (math.pi / h / n) * (2 * math.pi / w / n)).reshape(-1)
    dirs = dirs.reshape(-1, 3)
    cos_l = normals @ dirs.T  # (P, Q)
    diffuse = (np.clip(cos_l, 0, None) / math.pi * d_omega).sum(1)
    half = dirs[None] + views[:, None]
    half /= np.linalg.norm(half, axis=-1, keepdims=True)
    cos_h = (half * normals[:, None]).sum(-1)
    cos_v = (normals * views).sum(-1, keepdims=True)
    d = alpha**2 / (math.pi * ((alpha**2 - 1) * cos_h**2 + 1) ** 2)
    g1 = smith_g1(torch.tensor(cos_l), torch.tensor(alpha)).numpy()
    g2 = smith_g1(torch.tensor(cos_v), torch.tensor(alpha)).numpy()
    f_cos = np.where((cos_l > 0) & (cos_h > 0), d * g1 * g2 / (4 * cos_v), 0.0)
    return diffuse, (f_cos * d_omega).sum(1)


def _pixels_facing_the_sun(count: int, seed: int):
    """Normals within 60 degrees of the sun texel's centre, views within 50 degrees of
    the normal (``(P, 3)`` float64 each)."""
    theta, phi = (SUN_ROW + 0.5) * math.pi / 16, (SUN_COL + 0.5) * 2 * math.pi / 32
    sun = np.array(
        [math.sin(theta) * math.sin(phi), math.cos(theta), -math.sin(theta) * math.cos(phi)]
    )
    rng = np.random.default_rng(seed)
    normals, views = [], []
    while len(normals) < count:
        n = rng.normal(size=3)
        n /= np.linalg.norm(n)
        v = n + rng.normal(size=3) * 0.5
        v /= np.linalg.norm(v)
        if n @ sun > 0.5 and v @ n > 0.65:
            normals.append(n)
            views.append(v)
    return np.array(normals), np.array(views)


@pytest.mark.parametrize("alpha", [0.09, 0.36])
def test_bright_texels_match_brute_force_under_a_tiny_sun(alpha):
    """Per pixel, the MIS estimate is within a few percent of the quadrature, where plain
    BRDF sampling (the paper's) is off by far more: the speckle this removes."""
    normals, views = _pixels_facing_the_sun(100, seed=3)
    ref_d, ref_s = _texel_quadrature(normals, views, alpha)
    env = _sun_map(1.0)

    def estimate(max_bright):
        return coarse_shading(
            torch.tensor(normals),
            torch.tensor(views),
            torch.full((len(normals),), alpha, dtype=torch.float64),
            env,
            64,
            torch.Generator().manual_seed(4),
            max_bright=max_bright,
        )

    (mis_d, mis_s), (plain_d, _) = estimate(16), estimate(0)
    err_d = np.abs(mis_d[:, 0].numpy() - ref_d) / ref_d
    err_s = np.abs(mis_s[:, 0].numpy() - ref_s) / ref_s
    assert np.median(err_d) < 0.03 and np.median(err_s) < 0.1
    plain_err_d = np.abs(plain_d[:, 0].numpy() - ref_d) / ref_d
    assert np.median(plain_err_d) > 10 * np.median(err_d)
    # Both are unbiased: their means over the pixels agree with the reference's.
    assert float(mis_d[:, 0].mean()) == pytest.approx(ref_d.mean(), rel=0.02)
    assert float(mis_s[:, 0].mean()) == pytest.approx(ref_s.mean(), rel=0.05)


def test_a_map_without_bright_texels_is_shaded_as_by_plain_sampling():
    """The white furnace's constant map (and any map without a texel 8 x its mean) takes
    no light samples: the estimate is bit-identical to the plain estimator's."""
    n = torch.nn.functional.normalize(torch.randn(300, 3, dtype=torch.float64), dim=-1)
    env = torch.rand(16, 32, 3, dtype=torch.float64, generator=torch.Generator().manual_seed(5))
    assert bright_texels(env) is None
    a = coarse_shading(n, n, torch.full((300,), 0.2), env, 16, torch.Generator().manual_seed(6))
    b = coarse_shading(
        n, n, torch.full((300,), 0.2), env, 16, torch.Generator().manual_seed(6), max_bright=0
    )
    for x, y in zip(a, b, strict=True):
        assert torch.equal(x, y)


def test_bright_texel_density_integrates_to_one_and_samples_land_in_their_texel():
    env = torch.full((16, 32, 3), 0.2, dtype=torch.float64)
    env[3, 7], env[9, 30] = 400.0, 100.0
    bright = bright_texels(env)
    assert bright is not None
    texels = sorted(zip(bright.rows.tolist(), bright.cols.tolist(), strict=True))
    assert texels == [(3, 7), (9, 30)]
    # Chosen by power: radiance x solid angle (rows 3 and 9 of 16).
    p3 = 400 * math.sin(3.5 * math.pi / 16)
    p9 = 100 * math.sin(9.5 * math.pi / 16)
    np.testing.assert_allclose(
        sorted(bright.probability.tolist(), reverse=True),
        [p3 / (p3 + p9), p9 / (p3 + p9)],
        rtol=0.01,
    )
    _, solid = sh.latlong_directions(16, 32)
    assert float((bright.pdf.numpy() * solid).sum()) == pytest.approx(1.0, rel=5e-3)
    u = torch.rand(4000, 2, dtype=torch.float64, generator=torch.Generator().manual_seed(7))
    dirs, k = bright.sample(u, 16)
    theta = torch.arccos(dirs[:, 1].clamp(-1, 1))
    phi = torch.remainder(torch.atan2(dirs[:, 0], -dirs[:, 2]), 2 * math.pi)
    assert torch.equal((theta / math.pi * 16).long(), bright.rows[k])
    assert torch.equal((phi / (2 * math.pi) * 32).long(), bright.cols[k])
    # Texels are chosen by their power.
    share = (k == 0).double().mean().item()
    assert share == pytest.approx(bright.probability[0].item(), abs=0.03)
