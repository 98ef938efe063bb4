import math

import numpy as np
import pytest
import torch
import trimesh

from neurender.metaball import INVERSE_SQUARE, Kernel, Scene, field, surface_attributes
from neurender.metaballs import density_mesh as dm
from neurender.metaballs.evaluate import example_metrics
from neurender.metaballs.raymarch import render_gbuffers
from neurender.metaballs.scenes import MAX_DEPTH, MIN_DEPTH, pixel_rays

WYVILL = Kernel("wyvill", 2.0)
KERNELS = [WYVILL, Kernel("gaussian", 1.5, 2.0)]


def cluster(count: int, seed: int = 0) -> Scene:
    """Centres uniform in a sphere of radius 4 at depth 16, radii ``4 (0.15 / N)^(1/3)``
    (the balls fill 15% of its volume), random colours, Wyvill kernel of support 2."""
    g = torch.Generator().manual_seed(seed)
    direction = torch.randn(count, 3, generator=g, dtype=torch.float64)
    direction /= direction.norm(dim=1, keepdim=True)
    distance = 4 * torch.rand(count, 1, generator=g, dtype=torch.float64) ** (1 / 3)
    centres = direction * distance + torch.tensor([0.0, 0.0, 16.0], dtype=torch.float64)
    radii = torch.full((count,), 4 * (0.15 / count) ** (1 / 3), dtype=torch.float64)
    colours = torch.rand(count, 3, generator=g, dtype=torch.float64)
    return Scene(centres, radii, colours, WYVILL)


def one_ball(centre, kernel=WYVILL) -> Scene:
    f64 = torch.float64
    return Scene(
        torch.tensor([centre], dtype=f64),
        torch.ones(1, dtype=f64),
        torch.tensor([[0.2, 0.5, 0.9]], dtype=f64),
        kernel,
    )


def random_scene(kernel: Kernel) -> Scene:
    g = torch.Generator().manual_seed(3)
    count = 12
    centres = torch.rand(count, 3, generator=g, dtype=torch.float64) * 3 + torch.tensor(
        [-1.5, -1.5, 14.0], dtype=torch.float64
    )
    radii = 0.3 + 0.5 * torch.rand(count, generator=g, dtype=torch.float64)
    colours = torch.rand(count, 3, generator=g, dtype=torch.float64)
    return Scene(centres, radii, colours, kernel)


def grid_points(grid: dm.DensityGrid) -> torch.Tensor:
    """``(nx * ny * nz, 3)`` positions of the grid's points, in its volumes' order."""
    axes = [torch.arange(n, dtype=torch.float64) for n in grid.values.shape]
    ijk = torch.stack(torch.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    return grid.origin + ijk * grid.spacing


@pytest.mark.parametrize("kernel", KERNELS, ids=lambda k: k.name)
def test_grid_equals_brute_force_field(kernel):
    scene = random_scene(kernel)
    grid = dm.density_grid(scene, 0.15)
    points = grid_points(grid)
    truth, _ = field(points, scene)  # every ball at every point
    assert torch.allclose(grid.values.flatten().double(), truth, rtol=1e-5, atol=1e-6)
    reached = truth > 1e-3
    colour, _ = surface_attributes(points[reached], scene)
    assert torch.allclose(grid.colours.reshape(-1, 3)[reached].double(), colour, atol=1e-4)
    assert (grid.colours.reshape(-1, 3)[truth == 0] == 0).all()
    # The grid covers every ball's support: the field is 0 on its faces.
    v = grid.values
    for face in (v[0], v[-1], v[:, 0], v[:, -1], v[..., 0], v[..., -1]):
        assert (face == 0).all()
    # Chunking the balls finely changes nothing.
    chunked = dm.density_grid(scene, 0.15, max_pairs=500)
    assert torch.allclose(chunked.values, grid.values, atol=1e-6)
    assert torch.allclose(chunked.colours, grid.colours, atol=1e-6)


@pytest.mark.parametrize("kernel", KERNELS, ids=lambda k: k.name)
def test_single_ball_mesh_is_a_closed_sphere_of_radius_r(kernel):
    centre = np.array([0.31, -0.17, 16.04])
    spacing = 0.05
    scene = one_ball(centre.tolist(), kernel)
    grid = dm.density_grid(scene, spacing)
    vertices, faces, normals = dm.mesh_surface(grid.values, grid.origin, grid.spacing)
    offset = vertices - centre
    radius = np.linalg.norm(offset, axis=1)
    assert np.abs(radius - 1).max() < 0.05 * spacing
    radial = offset / radius[:, None]
    assert ((normals * radial).sum(1) > math.cos(math.radians(3))).all()  # outward
    # As marching cubes made it (no vertex merging): every edge has two faces, genus 0.
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    assert mesh.is_watertight
    assert mesh.euler_number == 2


@pytest.mark.parametrize("shading", dm.SHADINGS)
def test_single_ball_depth_matches_analytic_sphere(shading):
    spacing, width = 0.05, 33  # odd: the centre pixel's ray is the z axis
    scene = one_ball([0.0, 0.0, 16.0])
    buffers = dm.density_mesh(scene, width, spacing, shading=shading)
    centre = width // 2
    distance = float(buffers.depth[0, centre, centre]) * (MAX_DEPTH - MIN_DEPTH) + MIN_DEPTH
    assert distance == pytest.approx(15.0, abs=0.05 * spacing)
    normal = buffers.normal[:, centre, centre] * 2 - 1
    assert torch.allclose(normal.float(), torch.tensor([0.0, 0.0, -1.0]), atol=1e-3)
    assert torch.allclose(buffers.colour[:, centre, centre], scene.colours[0], atol=1e-5)
    # Silhouette: the pixels whose rays meet the sphere, away from its rim.
    dirs = pixel_rays(width).reshape(-1, 3)
    miss = (dirs @ scene.centres[0]).square() - (scene.centres[0].square().sum() - 1)
    mask = buffers.mask.flatten()
    assert mask[miss > 0.05].all() and not mask[miss < -0.05].any()


def test_rasterise_interpolates_a_plane():
    # A quad at z = 10 facing the camera: colours linear in x, y (reproduced exactly by
    # barycentric interpolation), normals not unit length (renormalised).
    vertices = np.array([[-5.0, -5, 10], [5, -5, 10], [5, 5, 10], [-5, 5, 10]])
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    colours = np.stack([(vertices[:, 0] + 5) / 10, (vertices[:, 1] + 5) / 10, np.full(4, 0.5)], 1)
    normals = np.tile([0.0, 0.0, -2.0], (4, 1))
    width = 16
    buffers = dm.rasterise(vertices, faces, normals, colours, width, threads=2)
    dirs = pixel_rays(width).reshape(-1, 3)
    hit = dirs * (10 / dirs[:, 2:])
    inside = (hit[:, :2].abs() < 4.9).all(1)
    outside = (hit[:, :2].abs() > 5.1).any(1)
    mask = buffers.mask.flatten()
    assert mask[inside].all() and not mask[outside].any()
    distance = buffers.depth.flatten() * (MAX_DEPTH - MIN_DEPTH) + MIN_DEPTH
    assert torch.allclose(distance[mask], hit[mask].norm(dim=1), atol=1e-4)
    colour = buffers.colour.reshape(3, -1)[:, mask].T
    expected = torch.stack([(hit[mask, 0] + 5) / 10, (hit[mask, 1] + 5) / 10], 1)
    assert torch.allclose(colour[:, :2].double(), expected, atol=1e-4)
    normal = buffers.normal.reshape(3, -1)[:, mask].T.float()
    assert torch.allclose(normal, torch.tensor([0.5, 0.5, 0.0]))
    assert (buffers.normal.reshape(3, -1)[:, ~mask] == 0).all()


def test_trilinear_reproduces_a_linear_volume():
    g = torch.Generator().manual_seed(1)
    origin, spacing = torch.tensor([1.0, -2.0, 3.0], dtype=torch.float64), 0.25
    ijk = grid_points(dm.DensityGrid(torch.zeros(5, 6, 7), origin, spacing, None))
    linear = torch.tensor([[1.0, 2.0], [-3.0, 0.5], [0.25, 4.0]], dtype=torch.float64)
    volume = (ijk @ linear + 1).reshape(5, 6, 7, 2)
    points = (
        origin
        + torch.rand(100, 3, generator=g, dtype=torch.float64)
        * torch.tensor([4.0, 5.0, 6.0], dtype=torch.float64)
        * spacing
    )
    got = dm.trilinear(volume, origin, spacing, points)
    assert torch.allclose(got, points @ linear + 1)


def test_quality_improves_as_the_grid_gets_finer():
    scene, width = cluster(200), 48
    truth = render_gbuffers(scene, width).stack()
    scores = [
        example_metrics(dm.density_mesh(scene, width, spacing).stack(), truth)
        for spacing in dm.spacing_settings(scene)[::2]  # shares 1, 0.5, 0.25 of a radius
    ]
    ious = [s["iou_depth"] for s in scores]
    angles = [s["normal_error_mean_deg"] for s in scores]
    assert ious == sorted(ious) and ious[-1] > 0.99
    assert angles == sorted(angles, reverse=True) and angles[-1] < angles[0] / 4


def test_ten_thousand_balls_at_a_coarse_spacing():
    # A tensor of every ball at every grid point would hold 10^4 x 6 10^5 values (24 GB).
    scene = cluster(10_000)
    spacing = dm.spacing_settings(scene)[0]
    grid = dm.density_grid(scene, spacing)
    assert len(scene) * grid.values.numel() > 5e9
    buffers = dm.density_mesh(scene, 32, spacing)
    # The balls fill 15% of a sphere of radius 4 that rays cross over several units: its
    # inside is opaque, and nothing lies beyond its radius plus a ball's reach (0.2).
    dirs = pixel_rays(32).reshape(-1, 3)
    centre = torch.tensor([0.0, 0.0, 16.0], dtype=torch.float64)
    miss = (centre.square().sum() - (dirs @ centre).square()).sqrt()  # ray to centre
    mask = buffers.mask.flatten()
    assert mask[miss < 3.5].all() and not mask[miss > 4.3].any()


def test_spacing_settings_are_shares_of_the_median_radius():
    scene = random_scene(WYVILL)
    median = float(np.median(scene.radii.numpy()))
    assert dm.spacing_settings(scene) == pytest.approx([s * median for s in dm.SPACING_SHARES])


def test_empty_and_invalid_inputs():
    scene = one_ball([0.0, 0.0, 16.0])
    vertices, faces, normals = dm.mesh_surface(torch.zeros(4, 4, 4), torch.zeros(3), 0.1)
    assert vertices.shape == (0, 3) and faces.shape == (0, 3) and normals.shape == (0, 3)
    assert not dm.rasterise(vertices, faces, normals, vertices, 8).mask.any()
    with pytest.raises(ValueError, match="spacing -0.1"):
        dm.density_grid(scene, -0.1)
    with pytest.raises(ValueError, match="inverse_square"):
        dm.density_grid(Scene(scene.centres, scene.radii, scene.colours, INVERSE_SQUARE), 0.1)
    with pytest.raises(ValueError, match="'phong'"):
        dm.density_mesh(scene, 8, 0.2, shading="phong")
