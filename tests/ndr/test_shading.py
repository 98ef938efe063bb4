import math

import numpy as np
import pytest
import torch

from neurender import sh
from neurender.ndr.shading import coarse_shading, lookup, smith_g1


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
