"""The prefiltered coarse shading against analytic answers and the importance-sampled
reference (:mod:`neurender.ndr.shading`)."""

import math

import numpy as np
import pytest
import torch

from neurender import lights, sh
from neurender.ndr import environments
from neurender.ndr import prefiltered as pf
from neurender.ndr.shading import coarse_shading
from tests.ndr.test_shading import _ggx_albedo_by_quadrature

#: No lights (one without power), as :func:`pf.bright_lights` gives for a map without
#: bright texels.
NO_LIGHTS = pf.bright_lights(np.ones((8, 16, 3)), np.ones((4, 8, 3)))[0]


def _normals(count: int, seed: int) -> torch.Tensor:
    g = torch.Generator().manual_seed(seed)
    return torch.nn.functional.normalize(
        torch.randn(count, 3, dtype=torch.float64, generator=g), dim=-1
    )


def _diffuse(normals: torch.Tensor, coefficients: torch.Tensor, lights_: torch.Tensor):
    """``S_D`` ``(P, 3)`` at ``normals`` ``(P, 3)`` of a map's SH and lights."""
    irradiance = pf.diffuse_polynomial(coefficients, lights_)
    return pf.diffuse_shading(normals.T, irradiance, lights_).T


def test_constant_map_gives_unit_diffuse_shading():
    """White furnace: the SH of a unit map is ``2 sqrt(pi)`` in ``y_0^0`` alone, and
    ``S_D`` is exactly 1 at every normal; from a projected 128 x 256 map to its
    quadrature's accuracy."""
    n = _normals(500, 0)
    exact = torch.zeros(25, 3, dtype=torch.float64)
    exact[0] = 2 * math.sqrt(math.pi)
    np.testing.assert_allclose(_diffuse(n, exact, NO_LIGHTS).numpy(), 1.0, atol=1e-12)
    projected = torch.from_numpy(sh.project_latlong(np.ones((128, 256, 3)), 5))
    np.testing.assert_allclose(_diffuse(n, projected, NO_LIGHTS).numpy(), 1.0, atol=2e-4)


def test_monomial_irradiance_is_the_sh_sum():
    """The diffuse shading's monomials give exactly the clamped-cosine-convolved SH sum
    (Ramamoorthi and Hanrahan's ``sum_k A_l c_k Y_k(n) / pi``, written out here), both for
    the map and for a light's own SH."""
    c = torch.randn(25, 3, dtype=torch.float64, generator=torch.Generator().manual_seed(11))
    n = _normals(400, 12)
    band = [math.isqrt(k) for k in range(25)]
    zonal = [sh.CLAMPED_COSINE_ZONAL[b] * math.sqrt(4 * math.pi / (2 * b + 1)) for b in band]
    a = torch.tensor(zonal, dtype=torch.float64) / math.pi
    expected = sh.eval_sh(n, 5) @ (a[:, None] * c)  # (P, 3)
    to_monomials, kernel = pf.irradiance_monomials(5)
    m = torch.stack(pf.monomials(*n.T), -1)  # (P, 18)
    np.testing.assert_allclose((m @ (to_monomials @ c)).numpy(), expected.numpy(), atol=1e-10)
    d = n[:5]  # a light's SH part: sum_k a_k Y_k(d) Y_k(n)
    light = sh.eval_sh(n, 5) @ (a[:, None] * sh.eval_sh(d, 5).T)  # (P, 5)
    np.testing.assert_allclose((m @ kernel @ m[:5].T).numpy(), light.numpy(), atol=1e-10)


def test_linear_map_gives_the_analytic_irradiance():
    """``L(w) = a + b (w.d)`` has ``S_D = a + 2 b (n.d) / 3`` (no clamp: ``a > b``)."""
    d = np.array([0.3, 0.8, -0.52])
    d /= np.linalg.norm(d)
    dirs, _ = sh.latlong_directions(64, 128)
    env = (1.0 + 0.6 * dirs @ d)[..., None] * np.array([1.0, 0.5, 0.25])
    coefficients = torch.from_numpy(sh.project_latlong(env, 5))
    n = _normals(300, 1)
    expected = (1.0 + 0.4 * n.numpy() @ d)[:, None] * np.array([1.0, 0.5, 0.25])
    np.testing.assert_allclose(_diffuse(n, coefficients, NO_LIGHTS).numpy(), expected, atol=1e-3)


def test_prefilter_rows_are_normalised_weights_and_level_zero_is_the_map():
    m = pf.prefilter_matrix(8)
    assert m.shape == (pf.LEVELS, 128, 128)
    assert (m >= 0).all()
    np.testing.assert_allclose(m.sum(-1).numpy(), 1.0, atol=1e-12)
    env = torch.rand(8, 16, 3, dtype=torch.float64, generator=torch.Generator().manual_seed(2))
    maps = pf.prefilter(env)
    assert torch.equal(maps[0], env)
    # Rougher levels blur more: the variance over the map falls level by level.
    spread = [float(level.var()) for level in maps]
    assert all(a > b for a, b in zip(spread, spread[1:], strict=False))


def test_map_lookup_at_texel_centres_reads_the_texels():
    """Bilinear lat-long reads in the convention of :mod:`neurender.sh`: texel centres
    return the texel; roughness between two levels interpolates them linearly."""
    maps = torch.rand(
        1, 2, 8, 16, 3, dtype=torch.float64, generator=torch.Generator().manual_seed(3)
    )
    dirs = torch.from_numpy(sh.latlong_directions(8, 16)[0]).reshape(1, -1, 3).transpose(1, 2)
    cells = pf.corner_cells(maps[0])[None]
    got = pf._map_lookup(cells, dirs, torch.zeros(1, 128, dtype=torch.float64))
    np.testing.assert_allclose(got[0].T.reshape(8, 16, 3).numpy(), maps[0, 0].numpy(), atol=1e-12)
    half = pf._map_lookup(cells, dirs, torch.full((1, 128), 0.25, dtype=torch.float64))
    expected = 0.75 * maps[0, 0] + 0.25 * maps[0, 1]
    np.testing.assert_allclose(half[0].T.reshape(8, 16, 3).numpy(), expected.numpy(), atol=1e-12)


def test_map_lookup_wraps_in_azimuth_and_clamps_at_the_poles():
    """Halfway between the last and the first column (azimuth 0, ``-z``) a read is their
    mean; between the poles and the first or last row's centre it reads that row alone;
    a batch reads each image's own maps."""
    maps = torch.rand(
        2, 3, 8, 16, 3, dtype=torch.float64, generator=torch.Generator().manual_seed(13)
    )
    theta = (torch.tensor([3.0, 0.1, 7.9]) / 8) * math.pi  # rows 2-3, above 0, below 7
    dirs = torch.stack([torch.zeros(3), theta.cos(), -theta.sin()], 0)[None].double()
    dirs = dirs.expand(2, -1, -1)
    cells = torch.stack([pf.corner_cells(m) for m in maps])
    got = pf._map_lookup(cells, dirs, torch.zeros(2, 3, dtype=torch.float64))  # (2, 3, 3)
    for b in range(2):
        first, last = maps[b, 0, :, 0], maps[b, 0, :, -1]
        expected = torch.stack(
            [
                (first[2] + first[3] + last[2] + last[3]) / 4,
                (first[0] + last[0]) / 2,
                (first[7] + last[7]) / 2,
            ]
        )
        np.testing.assert_allclose(got[b].T.numpy(), expected.numpy(), atol=1e-12)


def test_stacked_lights_add_nothing():
    """Padding a map's lights to a batch's count (:func:`pf.stack_lights`) leaves both
    shadings unchanged."""
    env = environments.sunlit_environment(np.random.default_rng(3), 32)
    light = pf.lighting(env, environments.resize_latlong(env, 16))
    one = light.lights
    padded = pf.stack_lights([one, pf.no_lights(5)])[:1]
    assert padded.shape == (1, 5, pf.LIGHT_COLUMNS)
    n = _normals(50, 14)
    v = torch.nn.functional.normalize(n + 0.5 * _normals(50, 15), dim=-1)
    alpha = torch.full((50,), 0.3, dtype=torch.float64)
    table = pf.albedo_table()
    shaded = [
        (
            pf.diffuse_shading(n.T[None], light.irradiance[None], k),
            pf.specular_shading(n.T[None], v.T[None], alpha[None], light.cells[None], table, k),
        )
        for k in (one[None], padded)
    ]
    for alone, with_padding in zip(*shaded, strict=True):
        np.testing.assert_allclose(with_padding.numpy(), alone.numpy(), atol=1e-12)


@pytest.mark.parametrize(
    ("cos_v", "roughness"), [(1.0, 0.45), (0.6, 0.7), (0.9, 0.95), (0.33, 0.3)]
)
def test_constant_map_gives_the_ggx_albedo(cos_v, roughness):
    """White furnace: every prefiltered level of a unit map is 1, so ``S_S`` is the albedo
    table's value, which matches an independent quadrature within 1 % (also between the
    table's entries)."""
    normals = torch.tensor([[0.0, 0.0, 1.0]], dtype=torch.float64)
    views = torch.tensor([[math.sqrt(1 - cos_v**2), 0.0, cos_v]], dtype=torch.float64)
    env = torch.ones(16, 32, 3, dtype=torch.float64)
    coefficients = torch.from_numpy(sh.project_latlong(env.numpy(), 5))
    alpha = torch.tensor([roughness**2], dtype=torch.float64)
    light = pf.map_lighting(coefficients, pf.prefilter(env), NO_LIGHTS)
    _, s_s = pf.prefiltered_shading(normals, views, alpha, light)
    expected = _ggx_albedo_by_quadrature(cos_v, roughness**2)
    np.testing.assert_allclose(s_s.numpy(), expected, rtol=0.01)


def test_batched_shading_is_the_shading_of_each_image():
    envs = [
        environments.sunlit_environment(np.random.default_rng(3), 32),
        lights.procedural_probe("studio", 32),
    ]
    lighting = [pf.lighting(e, environments.resize_latlong(e, 16)) for e in envs]
    maps = torch.stack([x.cells for x in lighting])
    bright = pf.stack_lights([x.lights for x in lighting])
    assert bright[0, :, 3:6].sum() > 0
    n = _normals(200, 4).reshape(2, 100, 3)
    v = torch.nn.functional.normalize(n + 0.7 * _normals(200, 5).reshape(2, 100, 3), dim=-1)
    n, v = n.transpose(1, 2), v.transpose(1, 2)  # channels first
    alpha = torch.rand(2, 100, dtype=torch.float64, generator=torch.Generator().manual_seed(6))
    both = pf.specular_shading(n, v, alpha, maps, pf.albedo_table(), bright)
    for b in range(2):
        one = pf.specular_shading(
            n[b : b + 1],
            v[b : b + 1],
            alpha[b : b + 1],
            maps[b : b + 1],
            pf.albedo_table(),
            bright[b : b + 1],
        )
        np.testing.assert_allclose(both[b].numpy(), one[0].numpy(), atol=1e-12)


#: Mean |fast - reference| / mean reference, S_D and S_S, that the fast shading stays within
#: on real maps against the coarse map's reference (measured here: at most 0.027 and 0.15;
#: benchmarks/results/coarse_shading_accuracy.csv).
REAL_MAP_TOLERANCE = {"S_D": 0.04, "S_S": 0.2}


@pytest.mark.parametrize("map_name", ["sky", "studio", "sunlit"])
@pytest.mark.parametrize("roughness", [0.2, 0.5, 0.9])
def test_real_maps_agree_with_the_importance_sampled_reference(map_name, roughness):
    """Camera-facing points (view along +z) under built-in and real-world-like maps: the
    fast shading's mean relative difference from the reference (256 samples per lobe,
    bright texels by MIS) stays within :data:`REAL_MAP_TOLERANCE`, and the means agree
    within 10 %."""
    if map_name == "sunlit":
        env = environments.sunlit_environment(np.random.default_rng(7), 128)
    else:
        env = lights.procedural_probe(map_name, 128)
    small = environments.resize_latlong(env, 16)
    light = pf.lighting(env, small)
    n = _normals(3000, 8)
    n = n[n[:, 2] > 0.05]
    v = torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64).expand_as(n)
    alpha = torch.full((len(n),), roughness**2, dtype=torch.float64)
    fast = pf.prefiltered_shading(n, v, alpha, light)
    ref = coarse_shading(
        n, v, alpha, torch.from_numpy(small), 256, torch.Generator().manual_seed(9)
    )
    for name, f, r in zip(("S_D", "S_S"), fast, ref, strict=True):
        rel = float((f - r).abs().mean() / r.mean())
        assert rel < REAL_MAP_TOLERANCE[name], (name, rel)
        assert float(f.mean() / r.mean()) == pytest.approx(1.0, abs=0.1), name


def _sun_map(direction: np.ndarray, radius: float, height: int = 128) -> np.ndarray:
    """A constant sky of radiance 0.2 and a disk sun of angular ``radius`` (radians) at
    unit ``direction`` holding power 6 per channel."""
    dirs, solid = sh.latlong_directions(height, 2 * height)
    inside = dirs @ direction > math.cos(radius)
    env = np.full((height, 2 * height, 3), 0.2)
    env[inside] += 6.0 / solid[inside].sum()
    return env


def test_bright_lights_keep_the_power_and_find_the_sun_inside_its_texel():
    """A sun of 1.5 degrees radius off the centre of its coarse texel (16 rows: texels of
    11 degrees): one light at the sun's direction (within a quarter degree) with its radius
    (within 20 %); the lights and the rest of the coarse map hold the coarse map's power;
    a map without bright texels gives no light and itself."""
    sun = np.array([0.41, 0.62, -0.67])
    sun /= np.linalg.norm(sun)
    env = _sun_map(sun, math.radians(1.5))
    small = environments.resize_latlong(env, 16)
    bright, rest = pf.bright_lights(env, small)
    assert bright.shape == (1, pf.LIGHT_COLUMNS)
    light = bright[0]
    angle = math.degrees(math.acos(min(1.0, float(light[0:3] @ torch.from_numpy(sun)))))
    assert angle < 0.25
    assert float(light[6]) == pytest.approx(math.radians(1.5), rel=0.2)
    _, solid = sh.latlong_directions(16, 32)
    power = (small * solid[..., None]).sum((0, 1))
    kept = (rest.numpy() * solid[..., None]).sum((0, 1)) + bright[:, 3:6].sum(0).numpy()
    np.testing.assert_allclose(kept, power, rtol=2e-3)
    flat = np.ones((16, 32, 3))
    none, same = pf.bright_lights(flat, flat)
    assert none.shape == (1, pf.LIGHT_COLUMNS) and float(none[:, 3:6].abs().sum()) == 0
    assert np.array_equal(same.numpy(), flat)


def test_a_sun_is_shaded_as_the_full_map_shades_it():
    """Under a small sun (most of the power) and a dim sky, both lobes within a few per cent
    of the importance-sampled reference on the full map (the light the renders see), and
    nearer to it than the importance estimator reading the coarse map (the paper's 64
    samples)."""
    sun = np.array([0.3, 0.8, 0.52])
    sun /= np.linalg.norm(sun)
    env = _sun_map(sun, math.radians(1.0))
    small = environments.resize_latlong(env, 16)
    n = _normals(3000, 10)
    n = n[n[:, 2] > 0.05]
    v = torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64).expand_as(n)
    g = torch.Generator().manual_seed(11)
    alpha = (0.2 + 0.8 * torch.rand(len(n), dtype=torch.float64, generator=g)) ** 2
    fast = pf.prefiltered_shading(n, v, alpha, pf.lighting(env, small))
    ref = coarse_shading(
        n, v, alpha, torch.from_numpy(env), 1024, torch.Generator().manual_seed(12)
    )
    paper = coarse_shading(
        n, v, alpha, torch.from_numpy(small), 64, torch.Generator().manual_seed(13)
    )
    for name, f, p, r in zip(("S_D", "S_S"), fast, paper, ref, strict=True):
        rel = float((f - r).abs().mean() / r.mean())
        assert rel < {"S_D": 0.005, "S_S": 0.02}[name], (name, rel)  # measured 3e-4, 2e-3
        assert rel < float((p - r).abs().mean() / r.mean()), name


def test_the_data_stage_writes_the_prefiltered_shading_when_asked():
    """``ndr.coarse_shading: prefiltered``: a sample's ``S_D``, ``S_S`` are the fast
    shading of its object's pixels under its map (SH of the full map, prefiltered copies
    of the coarse one), 0 off the object, and deterministic."""
    from neurender.ndr import data, render
    from tests.ndr.test_render import CFG

    cfg = {**CFG, "coarse_shading": "prefiltered"}
    obj, env, _, _ = data.sample_scene(cfg, "train", 0)
    g = render.g_buffers(obj, render.camera(cfg["camera_distance"], cfg["fov"]), cfg["width"])
    s_d, s_s = data.coarse_maps(cfg, g, env, "train", 0)
    m = g["mask"] > 0
    assert m.any() and (s_d[~m] == 0).all() and (s_s[~m] == 0).all()
    lighting = pf.lighting(env, environments.resize_latlong(env, cfg["coarse_height"]))
    expected = pf.prefiltered_shading(
        torch.from_numpy(g["normal"][m]).double(),
        torch.from_numpy(g["view_dir"][m]).double(),
        torch.from_numpy(g["roughness"][m]).double() ** 2,
        lighting,
    )
    np.testing.assert_allclose(s_d[m], expected[0].numpy(), rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(s_s[m], expected[1].numpy(), rtol=1e-5, atol=1e-6)
    again = data.coarse_maps(cfg, g, env, "train", 1)  # the key seeds nothing here
    assert np.array_equal(again[0], s_d) and np.array_equal(again[1], s_s)
