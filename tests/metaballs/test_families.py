import math

import numpy as np
import pytest
import torch

from neurender.metaball import Kernel, Scene
from neurender.metaballs import families, gbuffers, raymarch, scenes

FAMILIES = [families.cluster, families.sheet]
CENTRE = torch.tensor([0.0, 0.0, families.CENTRE_DEPTH], dtype=torch.float64)


def _gen(seed=0):
    return torch.Generator().manual_seed(seed)


@pytest.mark.parametrize("count", [100, 1000, 10000])
def test_cluster_packs_its_sphere_at_the_target_fraction(count):
    scene = families.cluster(count, _gen(count), packing=0.15)
    # The centres fill a sphere whose radius their farthest one underestimates by about
    # 1 / (3 count): the measured packing is the target or a little above.
    extent = float((scene.centres - CENTRE).norm(dim=1).max())
    packing = float(scene.radii.pow(3).sum()) / extent**3
    assert 0.15 <= packing <= 0.15 * 1.05
    # radii jittered +-30% around their mean, which shrinks as count^(-1/3)
    mean = float(scene.radii.mean())
    assert float(scene.radii.max() / scene.radii.min()) <= 1.3 / 0.7 + 1e-9
    assert 0.5 < mean * count ** (1 / 3) / (0.15 ** (1 / 3) * 7.5) < 1.0


@pytest.mark.parametrize("family", FAMILIES, ids=lambda f: f.__name__)
@pytest.mark.parametrize("count", [1, 100, 100000])
def test_every_balls_reach_is_inside_the_view_cone_and_beyond_the_near_plane(family, count):
    scene = family(count, _gen(1))
    reach = scene.reach
    distance = scene.centres.norm(dim=1)
    # angle of the centre off the view axis plus the reach's angular radius
    off_axis = torch.atan2(scene.centres[:, :2].norm(dim=1), scene.centres[:, 2])
    widest = torch.rad2deg(off_axis + torch.asin(reach / distance)).max()
    assert widest < scenes.FOV_DEG
    assert (distance - reach).min() > scenes.MIN_DEPTH + families.NEAR_GAP
    assert ((scene.centres - CENTRE).norm(dim=1) + reach).max() <= families.bound_radius() + 1e-9
    pixels = scenes.project(scene.centres, 64)
    assert ((pixels > 0) & (pixels < 64)).all()


@pytest.mark.parametrize("family", FAMILIES, ids=lambda f: f.__name__)
def test_a_family_is_a_function_of_its_seed(family):
    a, b, c = family(500, _gen(3)), family(500, _gen(3)), family(500, _gen(4))
    for name in ("centres", "radii", "colours"):
        assert torch.equal(getattr(a, name), getattr(b, name))
        assert not torch.equal(getattr(a, name), getattr(c, name))
    assert a.kernel == families.WYVILL
    assert ((a.colours >= 0) & (a.colours <= 1)).all()


def test_sheet_packs_its_slab_at_the_target_fraction():
    count, layers = 20000, 2.0
    scene = families.sheet(count, _gen(2), packing=0.15, layers=layers, tilt_deg=0.0)
    # Facing the camera (no tilt), the centres' x-y extent is the sheet's disc; the slab is
    # 2 layers rbar thick, rbar the radii's mean (their jitter averages to 0).
    disc = float(scene.centres[:, :2].norm(dim=1).max())
    slab = math.pi * disc**2 * 2 * layers * float(scene.radii.mean())
    packing = 4 / 3 * math.pi * float(scene.radii.pow(3).sum()) / slab
    assert packing == pytest.approx(0.15, rel=0.02)


@pytest.mark.parametrize("family", FAMILIES, ids=lambda f: f.__name__)
def test_families_reject_impossible_parameters(family):
    with pytest.raises(ValueError, match="packing fraction 1.5"):
        family(10, _gen(), packing=1.5)
    with pytest.raises(ValueError, match="at least one ball, not 0"):
        family(0, _gen())
    with pytest.raises(ValueError, match="radius_spread 1.0"):
        family(10, _gen(), radius_spread=1.0)


def _dense_reach_counts(scene, width):
    """Reference: every pixel's ray against every ball's sphere of reach."""
    rays = scenes.pixel_rays(width, scene.centres.dtype).reshape(-1, 3)
    b = rays @ scene.centres.T
    disc = b.square() - (scene.centres.square().sum(1) - scene.reach.square())
    return (disc > 0).sum(1)


def test_frame_stats_count_the_reach_spheres_of_covered_pixels():
    scene = families.cluster(300, _gen(5))
    width = 32
    g = raymarch.render_gbuffers(scene, width, bisections=8)
    stats = families.frame_stats(scene, g)
    mask = g.mask.reshape(-1)
    assert stats["covered"] == pytest.approx(float(mask.double().mean()))
    expected = float(_dense_reach_counts(scene, width)[mask].double().mean())
    assert stats["depth_complexity"] == pytest.approx(expected, rel=1e-12)
    assert stats["near_plane"] == 0


def test_frame_stats_of_a_lone_ball_and_of_the_near_plane(make_scene):
    lone = make_scene([[0.5, 0.0, 15.0]], [1.5])
    lone = Scene(lone.centres, lone.radii, lone.colours, Kernel("gaussian", 2.5))
    stats = families.frame_stats(lone, raymarch.render_gbuffers(lone, 32))
    # the surface lies inside the ball's reach: every covered ray crosses it once
    assert stats["depth_complexity"] == 1 and 0 < stats["covered"] < 0.2
    # hand-made buffers: pixel 1 missed, pixels 0 and 3 start inside (at MIN_DEPTH)
    distance = torch.tensor([scenes.MIN_DEPTH, math.inf, 12.0, scenes.MIN_DEPTH])
    zeros = torch.zeros(3, 4)
    buffers = gbuffers.from_hits(distance, zeros, zeros, 2)
    stats = families.frame_stats(make_scene([[0.0, 0.0, 9.0]] * 3, [1.0] * 3), buffers)
    assert stats == {"covered": 0.75, "near_plane": 0.5, "depth_complexity": 3.0}


COUNTS = [100, 1000, 10000, 100000]


@pytest.fixture(scope="module")
def cluster_stats():
    """Frame statistics of the cluster at 64 px by the exact renderer, per count (float32
    and 8 bisections: the mask and the depth at the near plane are what matter)."""
    out = {}
    for count in COUNTS:
        scene = families.cluster(count, _gen(count)).to(torch.float32)
        out[count] = families.frame_stats(scene, raymarch.render_gbuffers(scene, 64, bisections=8))
    return out


def test_no_cluster_pixel_starts_inside_the_surface(cluster_stats):
    assert all(s["near_plane"] == 0 for s in cluster_stats.values())


def test_cluster_coverage_stays_within_its_disc_and_fills_it_as_balls_shrink(cluster_stats):
    # the sphere of the bound projects to a disc of tan(asin(R / D)) / tan(FOV) of the
    # half-width
    ratio = math.tan(math.asin(families.bound_radius() / families.CENTRE_DEPTH))
    disc = math.pi * (ratio / math.tan(math.radians(scenes.FOV_DEG))) ** 2 / 4
    covered = [cluster_stats[n]["covered"] for n in COUNTS]
    assert max(covered) <= disc
    assert np.all(np.diff(covered) > 0)  # a sparse foam of big balls at 100
    assert covered[-1] > 0.85 * disc and covered[-2] > 0.8 * disc


def test_cluster_depth_complexity_grows_as_the_cube_root_of_the_count(cluster_stats):
    complexity = [cluster_stats[n]["depth_complexity"] for n in COUNTS]
    slope = np.polyfit(np.log(COUNTS), np.log(complexity), 1)[0]
    assert 0.27 < slope < 0.4
    assert np.all(np.diff(complexity) > 0)


def test_sheet_depth_complexity_stays_flat():
    complexity = []
    for count in (1000, 10000):
        scene = families.sheet(count, _gen(count)).to(torch.float32)
        g = raymarch.render_gbuffers(scene, 64, bisections=8)
        complexity.append(families.frame_stats(scene, g)["depth_complexity"])
    assert 0.8 < complexity[1] / complexity[0] < 1.25
