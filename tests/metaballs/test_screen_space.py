import dataclasses
import math

import numpy as np
import pytest
import torch
from torch.utils._python_dispatch import TorchDispatchMode

from neurender.metaball import Kernel, Scene
from neurender.metaballs import evaluate, inputs, raymarch, scenes
from neurender.metaballs.screen_space import (
    ScreenSpace,
    focal_pixels,
    screen_space_fluid,
    screen_space_settings,
    smooth_depth,
)

SPAN = scenes.MAX_DEPTH - scenes.MIN_DEPTH


def distance(buffers) -> torch.Tensor:
    """``(W, W)`` distance along the ray (world units) of G-buffers' normalised depth."""
    return buffers.depth[0] * SPAN + scenes.MIN_DEPTH


def sphere_z(centre, radius: float, width: int) -> np.ndarray:
    """``(W, W)`` view-space ``z`` of a sphere's near hit along each pixel ray (nan: miss)."""
    rays = scenes.pixel_rays(width).numpy()
    c = np.asarray(centre, dtype=float)
    b = rays @ c
    disc = b**2 - (c @ c - radius**2)
    t = np.where(disc >= 0, b - np.sqrt(np.clip(disc, 0, None)), np.nan)
    return t * rays[..., 2]


def within(scene: Scene, width: int, fraction: float) -> torch.Tensor:
    """``(W, W)`` pixels within ``fraction`` of the first ball's projected radius of its
    projected centre."""
    centre = scenes.project(scene.centres, width)[0]
    pixel = torch.arange(width) + 0.5
    rows, cols = torch.meshgrid(pixel, pixel, indexing="ij")
    projected = float(inputs.projected_radius(scene, width)[0])
    return torch.hypot(cols - centre[0], rows - centre[1]) < fraction * projected


def test_lone_ball_unfiltered_is_its_sphere(make_scene):
    scene = make_scene([[0.5, 0.3, 14.0]], [2.0])
    ours = screen_space_fluid(scene, 64, filter_radius=0.0)
    exact = inputs.draw_spheres(scene, 64)
    assert torch.equal(ours.mask, exact.mask)
    np.testing.assert_allclose(ours.depth, exact.depth, atol=1e-12)
    np.testing.assert_allclose(ours.colour, exact.colour, atol=1e-12)
    angles = evaluate.normal_angles(ours.stack(), exact.stack(), exact.mask)
    assert angles.mean() < 3  # one-sided differences of a steep rim are off by more
    inner = evaluate.normal_angles(ours.stack(), exact.stack(), within(scene, 64, 0.8))
    assert inner.max() < 2


def test_lone_ball_centre_is_the_filters_gaussian_mean_of_the_sphere(make_scene):
    """At the centre pixel one 2D pass averages the analytic sphere depth over the disc of
    the filter radius (no sample is out of range or in front)."""
    centre, r, width = [0.0, 0.0, 14.0], 2.0, 64
    scene = make_scene([centre], [r])
    setting = ScreenSpace()
    ours = screen_space_fluid(scene, width, **dataclasses.asdict(setting))
    z = sphere_z(centre, r, width)
    i, j = width // 2, width // 2
    radius = min(setting.filter_radius * r * focal_pixels(width) / z[i, j], setting.max_radius)
    sigma, total, weight = radius / 3, z[i, j], 1.0
    reach = math.floor(radius)
    for dy in range(-reach, reach + 1):
        for dx in range(-reach, reach + 1):
            d = math.hypot(dy, dx)
            if 0 < d <= radius and not np.isnan(z[i + dy, j + dx] + z[i - dy, j - dx]):
                total += math.exp(-(d**2) / (2 * sigma**2)) * z[i + dy, j + dx]
                weight += math.exp(-(d**2) / (2 * sigma**2))
    ray = scenes.pixel_rays(width)[i, j]
    np.testing.assert_allclose(float(distance(ours)[i, j] * ray[2]), total / weight, rtol=1e-9)
    # A sphere flattens by about (sigma in world units)^2 / r: a filter of a third of
    # its projected radius hardly changes it.
    small = screen_space_fluid(scene, width, filter_radius=1 / 3)
    assert 0 < distance(small)[i, j] * ray[2] - z[i, j] < 0.02 * r


def test_lone_ball_normals_face_the_camera_away_from_the_silhouette(make_scene):
    scene = make_scene([[0.5, 0.3, 14.0]], [2.0])
    ours = screen_space_fluid(scene, 64, filter_radius=0.5)
    exact = inputs.draw_spheres(scene, 64)
    angles = evaluate.normal_angles(ours.stack(), exact.stack(), within(scene, 64, 0.7))
    assert angles.max() < 4
    normals = ours.normal[:, ours.mask] * 2 - 1
    rays = scenes.pixel_rays(64).permute(2, 0, 1)[:, ours.mask]
    assert ((normals * rays).sum(0) < 0).all()  # every normal faces the camera
    np.testing.assert_allclose(normals.norm(dim=0), 1, atol=1e-9)


def test_background_stays_background(make_scene):
    scene = make_scene([[-2.0, 1.0, 12.0], [2.5, -1.0, 18.0]], [1.0, 2.0])
    ours = screen_space_fluid(scene, 48, iterations=2)
    exact = inputs.draw_spheres(scene, 48)
    assert torch.equal(ours.mask, exact.mask) and (~ours.mask).any()
    assert (ours.depth[0][~ours.mask] == 1).all()
    assert (ours.normal[:, ~ours.mask] == 0).all() and (ours.colour[:, ~ours.mask] == 0).all()
    assert torch.isfinite(ours.stack()).all()


def grid_plane(count: int, spacing: float, depth: float) -> Scene:
    """``count^2`` unit balls on a square grid centred on the optical axis at ``z = depth``."""
    k = (torch.arange(count, dtype=torch.float64) - (count - 1) / 2) * spacing
    gy, gx = torch.meshgrid(k, k, indexing="ij")
    centres = torch.stack([gx.flatten(), gy.flatten(), torch.full((count**2,), depth)], 1)
    gen = torch.Generator().manual_seed(1)
    colours = torch.rand(count**2, 3, dtype=torch.float64, generator=gen)
    return Scene(centres, torch.ones(count**2, dtype=torch.float64), colours)


@pytest.mark.parametrize("separable", [False, True])
@pytest.mark.parametrize("method", ["narrow_range", "bilateral"])
def test_plane_of_overlapping_balls_is_smoothed_flat(method, separable):
    scene, width = grid_plane(12, 0.8, 15.0), 64
    rays = scenes.pixel_rays(width)
    inner = ((rays[..., :2] / rays[..., 2:]).abs() * 15 < 2.5).all(-1)  # far from the edges
    assert inner.sum() > 200
    views = {}
    for name, radius in (("splats", 0.0), ("filtered", 3.0)):
        out = screen_space_fluid(scene, width, radius, method=method, separable=separable)
        assert out.mask[inner].all()
        z = (distance(out) * rays[..., 2])[inner]
        normals = out.normal[:, inner] * 2 - 1
        views[name] = z.var(), torch.rad2deg(torch.acos(-normals[2].clamp(-1, 1)))
    (raw, raw_angles), (smooth, angles) = views["splats"], views["filtered"]
    assert smooth < 0.01 * raw  # the bumps between the balls are gone
    assert raw_angles.mean() > 5 and angles.max() < 2  # normals near (0, 0, -1)


def test_narrow_range_keeps_a_depth_discontinuity(make_scene):
    centres, radii, width = [[-0.8, 0.0, 10.0], [0.8, 0.0, 20.0]], [1.5, 1.5], 64
    both = make_scene(centres, radii)
    _, ball = inputs.sphere_hits(both, width)
    near, far = (ball == 0).reshape(width, width), (ball == 1).reshape(width, width)
    assert near.any() and far.any()
    depths = {}
    for depth_range in (2.0, 100.0):  # 100 r: a plain Gaussian, blind to the gap of 10
        out = [
            distance(screen_space_fluid(s, width, depth_range=depth_range))
            for s in (both, make_scene(centres[:1], radii[:1]), make_scene(centres[1:], radii[1:]))
        ]
        depths[depth_range] = out
    together, alone_near, alone_far = depths[2.0]
    # The near ball's samples of the far one are behind its range, ignored as the
    # background is: its depths are those it has alone.
    np.testing.assert_allclose(together[near], alone_near[near], atol=1e-9)
    # The far ball's are pulled forward by at most clamp r = 1.5 (normalised: / ray z).
    pull = (alone_far - together)[far]
    assert (pull >= -1e-9).all() and pull.max() > 0.1 and (pull <= 1.5 / 0.96).all()
    blurred, blurred_near, _ = depths[100.0]
    assert (blurred - blurred_near)[near].abs().max() > 1  # without the range it blurs


def reference_narrow_range(z, radius, mu, clamp, separable):
    """One narrow-range iteration, one pixel at a time (the module docstring's filter)."""
    width = len(z)
    passes = (
        [[(0, k) for k in range(1, 8)], [(k, 0) for k in range(1, 8)]]
        if separable
        else [
            sorted(
                [
                    (dy, dx)
                    for dy in range(0, 8)
                    for dx in range(-7, 8)
                    if (dy > 0 or dx > 0) and math.hypot(dy, dx) <= 7
                ],
                key=lambda o: (math.hypot(*o), o[0], o[1]),
            )
        ]
    )

    def at(img, i, j):
        return img[i, j] if 0 <= i < width and 0 <= j < width else math.inf

    for offsets in passes:
        out = z.copy()
        for i, j in zip(*np.nonzero(np.isfinite(z)), strict=True):
            c = z[i, j]
            upper, lower = [c + mu[i, j]] * 2, [c - mu[i, j]] * 2
            total, weight = c, 1.0
            for dy, dx in offsets:
                d = math.hypot(dy, dx)
                if d > radius[i, j]:
                    continue
                w = math.exp(-(d**2) / (2 * (radius[i, j] / 3) ** 2))
                pair = []
                for side, sign in enumerate((1, -1)):
                    s = 0 if not separable else side
                    v = at(z, i + sign * dy, j + sign * dx)
                    if v > upper[s]:
                        pair.append(None)
                    elif v < lower[s]:
                        pair.append(c - clamp[i, j])
                    else:
                        pair.append(v)
                        upper[s], lower[s] = (
                            max(upper[s], v + mu[i, j]),
                            min(lower[s], v - mu[i, j]),
                        )
                if None not in pair:
                    total += w * sum(pair)
                    weight += 2 * w
            out[i, j] = total / weight
        z = out
    return z


@pytest.mark.parametrize("separable", [False, True])
def test_narrow_range_matches_a_per_pixel_reference(separable):
    gen = torch.Generator().manual_seed(3)
    width = 20
    z = 10 + torch.rand(width, width, generator=gen, dtype=torch.float64)
    z[torch.rand(width, width, generator=gen) < 0.2] += 3  # a surface behind
    z[torch.rand(width, width, generator=gen) < 0.2] -= 3  # and one in front
    z[torch.rand(width, width, generator=gen) < 0.15] = math.inf  # holes of background
    radius = 1 + 6 * torch.rand(width, width, generator=gen, dtype=torch.float64)
    r = 0.2 + torch.rand(width, width, generator=gen, dtype=torch.float64)
    colour = torch.zeros(3, width, width, dtype=torch.float64)
    ours, _ = smooth_depth(z, colour, radius, r, separable=separable, depth_range=2, clamp=1)
    want = reference_narrow_range(
        z.numpy(), radius.numpy(), 2 * r.numpy(), r.numpy(), separable=separable
    )
    np.testing.assert_allclose(ours.numpy(), want, rtol=1e-12)


def test_colour_is_the_nearest_balls_blended_by_the_depth_filter(make_scene):
    scene = make_scene([[-0.6, 0.0, 14.0], [0.6, 0.0, 14.0]], [1.0, 1.0])
    ours = screen_space_fluid(scene, 48)
    splats = inputs.draw_spheres(scene, 48)
    colours = ours.colour[:, ours.mask]
    lo, hi = scene.colours.min(0).values, scene.colours.max(0).values  # convex blends
    assert ((colours >= lo[:, None] - 1e-12) & (colours <= hi[:, None] + 1e-12)).all()
    assert not torch.allclose(ours.colour, splats.colour)  # blended at the seam


def test_deterministic_and_in_the_scenes_dtype():
    scene = scenes.sample_scene(30, (0.5, 1.2), torch.Generator().manual_seed(2))
    for setting in (ScreenSpace(), ScreenSpace(separable=True, method="bilateral")):
        a = screen_space_fluid(scene, 40, **dataclasses.asdict(setting)).stack()
        b = screen_space_fluid(scene, 40, **dataclasses.asdict(setting)).stack()
        assert torch.equal(a, b)
    single = screen_space_fluid(scene.to(torch.float32), 40)
    assert single.depth.dtype == torch.float32


def test_settings_run_the_unfiltered_splats_first():
    settings = screen_space_settings()
    assert settings[0].filter_radius == 0 and len({s.label for s in settings}) == len(settings)
    scene = scenes.sample_scene(5, (1.0, 2.0), torch.Generator().manual_seed(5))
    for s in settings:
        out = screen_space_fluid(scene, 24, **dataclasses.asdict(s))
        assert torch.isfinite(out.stack()).all()


def test_rejects_unknown_methods_and_negative_radii(make_scene):
    scene = make_scene([[0.0, 0.0, 12.0]], [1.0])
    with pytest.raises(ValueError, match="'gaussian'"):
        screen_space_fluid(scene, 16, method="gaussian")
    with pytest.raises(ValueError, match="-1"):
        screen_space_fluid(scene, 16, filter_radius=-1)


class LargestTensor(TorchDispatchMode):
    """Records the most elements of any tensor an operation returns."""

    def __init__(self):
        super().__init__()
        self.largest = 0

    def __torch_dispatch__(self, func, types, args=(), kwargs=None):
        out = func(*args, **(kwargs or {}))
        for t in out if isinstance(out, tuple | list) else (out,):
            if isinstance(t, torch.Tensor):
                self.largest = max(self.largest, t.numel())
        return out


def test_cost_follows_covered_pixels_not_balls():
    count, width = 20000, 64
    gen = torch.Generator().manual_seed(6)
    u = torch.rand(count, 3, generator=gen, dtype=torch.float64)
    centres = torch.stack([(u[:, 0] - 0.5) * 10, (u[:, 1] - 0.5) * 10, 12 + 8 * u[:, 2]], 1)
    radii = torch.full((count,), 0.02, dtype=torch.float64)
    scene = Scene(centres, radii, torch.rand(count, 3, generator=gen, dtype=torch.float64))
    with LargestTensor() as probe:
        out = screen_space_fluid(scene, width)
    assert out.mask.any()
    # every array is of a few values per ball or per pixel of a ball's box, never B x W^2
    assert probe.largest < 64 * (count + width**2) < count * width**2 / 50


def cluster(count: int, seed: int = 0) -> Scene:
    """``count`` balls uniform in a sphere of radius 4 at depth 16, packing 0.15, Wyvill."""
    gen = torch.Generator().manual_seed(seed)
    d = torch.randn(count, 3, generator=gen, dtype=torch.float64)
    shell = torch.rand(count, 1, generator=gen, dtype=torch.float64) ** (1 / 3) * 4
    centres = d / d.norm(dim=1, keepdim=True) * shell + torch.tensor([0.0, 0.0, 16.0])
    radii = torch.full((count,), 4 * (0.15 / count) ** (1 / 3), dtype=torch.float64)
    colours = torch.rand(count, 3, generator=gen, dtype=torch.float64)
    return Scene(centres, radii, colours, Kernel("wyvill", 2.0)).to(torch.float32)


def test_cluster_silhouette_matches_the_ray_marcher():
    scene = cluster(2000)
    truth = raymarch.render_gbuffers(scene, 64).stack()
    metrics = evaluate.example_metrics(screen_space_fluid(scene, 64).stack(), truth)
    assert metrics["iou_depth"] > 0.9
    assert metrics["depth_error_world"] < 0.5  # a tenth of the cluster's radius
