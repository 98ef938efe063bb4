"""Framing world balls in the metaballs' view space: inside the frustum, a similarity, the
scale on the radii."""

import math

import numpy as np
import pytest
import torch
from scipy.spatial.distance import pdist
from scipy.spatial.transform import Rotation

from neurender.metaballs import framing, scenes
from neurender.metaballs.framing import CENTRE_DEPTH, fit_framing, frame_balls
from neurender.metaballs.molecules import (
    FLUID,
    FLUID_RADIUS,
    PDB_ENTRIES,
    STRUCTURES,
    read_particles,
    read_structure,
)

WIDTH = 64


def random_balls(count, spread, seed):
    """World balls: positions ``(count, 3)`` around an offset, radii, colours."""
    rng = np.random.default_rng(seed)
    positions = rng.normal(size=(count, 3)) * spread + rng.uniform(-100, 100, 3)
    radii = rng.uniform(0.05, 0.2, count) * spread
    return positions, radii, rng.uniform(0, 1, (count, 3))


def assert_in_frustum(scene):
    """Every ball's centre projects inside the image and every ball's nearest surface point
    lies deeper than MIN_DEPTH (and its farthest before MAX_DEPTH)."""
    pixels = scenes.project(scene.centres, WIDTH)
    assert ((pixels > 0) & (pixels < WIDTH)).all()
    distance = scene.centres.norm(dim=1)
    assert (distance - scene.radii > scenes.MIN_DEPTH).all()
    assert (distance + scene.radii < scenes.MAX_DEPTH).all()
    # each ball's silhouette stays inside the 30-degree cone (tighter than the image square)
    half_angle = torch.atan2(scene.centres[:, :2].norm(dim=1), scene.centres[:, 2])
    silhouette = half_angle + torch.asin(scene.radii / distance)
    assert (silhouette < math.radians(scenes.FOV_DEG)).all()


@pytest.mark.parametrize(("count", "spread", "seed"), [(1, 1.0, 0), (50, 3.0, 1), (2000, 30.0, 2)])
@pytest.mark.parametrize("scale", [0.5, 1.0, 2.0])
def test_framed_balls_lie_inside_the_frustum(count, spread, seed, scale):
    scene, fit = frame_balls(*random_balls(count, spread, seed), scale=scale)
    assert scene.centres.dtype == scene.radii.dtype == scene.colours.dtype == torch.float64
    assert_in_frustum(scene)
    # the bounding sphere sits on the view axis at mid depth, as large as the margins allow
    centre = fit.points(fit.centre[None])[0]
    np.testing.assert_allclose(centre, [0, 0, CENTRE_DEPTH], atol=1e-12)
    reach = (scene.centres - torch.from_numpy(centre)).norm(dim=1) + scene.radii
    assert reach.max().item() == pytest.approx(framing.view_radius())


def test_the_view_radius_keeps_both_margins():
    rho = framing.view_radius()
    assert CENTRE_DEPTH - rho >= scenes.MIN_DEPTH + framing.NEAR_MARGIN - 1e-12
    tan_silhouette = math.tan(math.asin(rho / CENTRE_DEPTH))
    edge = math.tan(math.radians(scenes.FOV_DEG))
    assert tan_silhouette <= (1 - framing.IMAGE_MARGIN) * edge + 1e-12
    assert tan_silhouette > 0.9 * edge  # not needlessly small


@pytest.mark.parametrize("use_rotation", [False, True])
def test_framing_is_a_similarity_with_the_reported_scale(use_rotation):
    positions, radii, colours = random_balls(300, 5.0, 3)
    rotation = Rotation.from_euler("xyz", [30, -50, 110], degrees=True).as_matrix()
    scene, fit = frame_balls(positions, radii, colours, rotation=rotation if use_rotation else None)
    view = scene.centres.numpy()
    # every distance shrinks by the same factor, world_per_view
    np.testing.assert_allclose(pdist(view) * fit.world_per_view, pdist(positions), rtol=1e-10)
    np.testing.assert_allclose(scene.radii.numpy() * fit.world_per_view, radii, rtol=1e-12)
    # and no reflection: the handedness of every triangle is kept
    a, b, c = view[:3] - view[3]
    x, y, z = positions[:3] - positions[3]
    assert np.sign(np.dot(a, np.cross(b, c))) == np.sign(np.dot(x, np.cross(y, z)))
    np.testing.assert_array_equal(scene.colours.numpy(), colours)


def test_a_rotation_turns_the_balls_about_their_centre_at_the_same_scale():
    positions, radii, colours = random_balls(100, 2.0, 4)
    quarter = Rotation.from_euler("y", 90, degrees=True).as_matrix()
    plain, fit = frame_balls(positions, radii, colours)
    turned, turned_fit = frame_balls(positions, radii, colours, rotation=quarter)
    assert turned_fit.world_per_view == fit.world_per_view
    mid = np.array([0, 0, CENTRE_DEPTH])
    np.testing.assert_allclose(
        turned.centres.numpy() - mid, (plain.centres.numpy() - mid) @ quarter.T, atol=1e-12
    )


def test_the_scale_multiplies_the_radii_before_framing():
    positions, radii, colours = random_balls(20, 1.0, 5)
    for scale in (0.25, 1.0, 3.0):
        scene, fit = frame_balls(positions, radii, colours, scale=scale)
        assert fit.ball_scale == scale
        np.testing.assert_allclose(scene.radii.numpy() * fit.world_per_view, radii * scale)
    # with a shared framing the scale changes only the radii
    fit = fit_framing(positions, radii)
    small = fit.scene(positions, radii, colours)
    double = framing.Framing(fit.centre, fit.rotation, fit.world_per_view, 2.0)
    large = double.scene(positions, radii, colours)
    torch.testing.assert_close(large.radii, 2 * small.radii)
    torch.testing.assert_close(large.centres, small.centres)


def test_a_trajectory_fitted_once_keeps_one_camera():
    positions, radii, colours = random_balls(40, 2.0, 6)
    frames = [positions + np.array([t, 0.0, 0.0]) for t in range(3)]
    fit = fit_framing(np.concatenate(frames), np.tile(radii, 3))
    scenes_ = [fit.scene(f, radii, colours) for f in frames]
    for scene in scenes_:
        assert_in_frustum(scene)
    shift = (scenes_[1].centres - scenes_[0].centres).numpy()
    np.testing.assert_allclose(shift, np.tile([1 / fit.world_per_view, 0, 0], (40, 1)))


def test_a_molecule_and_the_fluid_frame_fit_with_their_units():
    atoms = read_structure(STRUCTURES / PDB_ENTRIES["1a28"])
    scene, fit = frame_balls(atoms.positions, atoms.radii, atoms.colours, scale=0.8)
    assert_in_frustum(scene)
    assert 1 < fit.world_per_view < 20  # angstroms per view unit for a ~60 A protein
    fluid = read_particles(STRUCTURES / FLUID, FLUID_RADIUS)
    scene, fit = frame_balls(fluid.positions, fluid.radii, fluid.colours)
    assert_in_frustum(scene)
    assert 0.1 < fit.world_per_view < 1  # metres per view unit for a 4 m tank
    # y (the simulation's up) stays up: the water lies low in the image
    assert scene.centres[:, 1].median() < 0


@pytest.mark.parametrize(
    ("positions", "radii", "colours", "kwargs", "message"),
    [
        (np.zeros((2, 2)), np.ones(2), np.zeros((2, 3)), {}, r"positions \(N, 3\)"),
        (np.zeros((0, 3)), np.ones(0), np.zeros((0, 3)), {}, "no balls"),
        (np.zeros((2, 3)), np.array([1.0, 0.0]), np.zeros((2, 3)), {}, "not positive"),
        (np.full((1, 3), np.nan), np.ones(1), np.zeros((1, 3)), {}, "finite"),
        (np.zeros((1, 3)), np.ones(1), np.full((1, 3), 2.0), {}, r"in \[0, 1\]"),
        (np.zeros((1, 3)), np.ones(1), np.zeros((1, 4)), {}, "expected colours"),
        (np.zeros((1, 3)), np.ones(1), np.zeros((1, 3)), {"scale": 0.0}, "positive number"),
        (np.zeros((1, 3)), np.ones(1), np.zeros((1, 3)), {"rotation": np.eye(2)}, "3x3"),
        (np.zeros((1, 3)), np.ones(1), np.zeros((1, 3)), {"rotation": -np.eye(3)}, "reflection"),
        (np.zeros((1, 3)), np.ones(1), np.zeros((1, 3)), {"rotation": 2 * np.eye(3)}, "normal"),
    ],
)  # fmt: skip
def test_bad_balls_are_refused_saying_why(positions, radii, colours, kwargs, message):
    with pytest.raises(ValueError, match=message):
        frame_balls(positions, radii, colours, **kwargs)
