import math

import pytest
import torch

from neurender.metaball import Kernel, Scene, field, march, surface_attributes
from neurender.metaballs import raymarch, scenes
from neurender.metaballs.grid import MAX_CELLS, build_grid

FINITE = [Kernel("wyvill", 2.0), Kernel("gaussian", 2.5, 1.0)]


def _scene(count, kernel, seed=0):
    s = scenes.sample_scene(count, (0.8, 2.0), torch.Generator().manual_seed(seed))
    return Scene(s.centres, s.radii, s.colours, kernel)


@pytest.mark.parametrize("kernel", FINITE, ids=lambda k: k.name)
def test_every_ball_reaching_a_cell_is_listed_there(kernel):
    scene = _scene(30, kernel)
    grid = build_grid(scene)
    points = grid.lower + torch.rand(2000, 3, dtype=torch.float64) * (grid.upper - grid.lower)
    owner, ball = grid.pairs(grid.cell_of(points))
    listed = torch.zeros(len(points), len(scene), dtype=torch.bool)
    listed[owner, ball] = True
    reaching = torch.cdist(points, scene.centres) < scene.reach
    assert not (reaching & ~listed).any()
    assert len(owner) < 0.5 * len(points) * len(scene)  # and the lists are culled


@pytest.mark.parametrize("kernel", FINITE, ids=lambda k: k.name)
def test_grid_field_and_attributes_equal_the_sum_over_every_ball(kernel):
    scene = _scene(25, kernel, seed=1)
    grid = build_grid(scene)
    points = scene.centres[:10] + 0.9 * scene.radii[:10, None] * torch.tensor([0.6, 0.0, -0.8])
    torch.testing.assert_close(grid.field(points), field(points, scene)[0], rtol=1e-12, atol=1e-12)
    for ours, theirs in zip(
        grid.surface_attributes(points), surface_attributes(points, scene), strict=True
    ):
        torch.testing.assert_close(ours, theirs, rtol=1e-10, atol=1e-10)


@pytest.mark.parametrize("kernel", FINITE, ids=lambda k: k.name)
def test_grid_marcher_equals_the_marcher_over_every_ball(kernel):
    scene = _scene(15, kernel, seed=2)
    dirs = scenes.pixel_rays(40).reshape(-1, 3)
    origins = torch.zeros_like(dirs)
    brute = march(origins, dirs, scene, scenes.MIN_DEPTH, scenes.MAX_DEPTH, 0.02)
    grid = build_grid(scene).march(origins, dirs, scenes.MIN_DEPTH, scenes.MAX_DEPTH, 0.02)
    hit = torch.isfinite(brute)
    assert hit.float().mean() > 0.2
    assert torch.equal(hit, torch.isfinite(grid))
    assert (brute[hit] - grid[hit]).abs().max() < 1e-6


def test_isolated_ball_of_a_finite_kernel_is_a_sphere_of_its_radius():
    scene = Scene(
        torch.tensor([[0.0, 0.0, 15.0]], dtype=torch.float64),
        torch.tensor([2.0], dtype=torch.float64),
        torch.tensor([[0.2, 0.4, 0.6]], dtype=torch.float64),
        Kernel("wyvill", 2.0),
    )
    g = raymarch.render_gbuffers(scene, 33)
    assert g.depth[0, 16, 16] == pytest.approx((13.0 - 7.0) / 18.0, abs=1e-6)
    torch.testing.assert_close(
        g.normal[:, 16, 16], torch.tensor([0.5, 0.5, 0.0], dtype=g.normal.dtype), atol=1e-6, rtol=0
    )
    inside = torch.acos(scenes.pixel_rays(33)[..., 2]) < math.asin(2.0 / 15.0)
    assert (inside == g.mask).float().mean() > 0.99


def test_a_grid_never_holds_more_than_its_cell_cap():
    scene = _scene(4, Kernel("wyvill", 2.0))
    grid = build_grid(scene, cell=1e-3)
    assert int(grid.dims.prod()) <= MAX_CELLS
    assert len(grid.starts) == int(grid.dims.prod()) + 1


def test_cell_lists_refuse_the_inverse_square():
    with pytest.raises(ValueError, match="finite support"):
        build_grid(_scene(3, Kernel()))
