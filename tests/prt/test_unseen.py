import numpy as np
import pytest

from neurender.geometry import grid_normals
from neurender.prt import unseen, unshadowed
from neurender.rng import stable_seed


def _dome(n=24):
    t = np.linspace(-1.0, 1.0, n)
    yy, xx = np.meshgrid(t, t, indexing="ij")
    return np.stack([1.5 * xx, yy, 0.4 * np.exp(-(xx**2 + yy**2) / 0.3)], -1)


def _deltas(n=24):
    rng = np.random.default_rng(0)
    return rng.normal(scale=0.05, size=(3, n, n, 3))


def _deform(family, strength, seed=0, index=0):
    return unseen.deform(_dome(), family, strength, seed, index, deltas=_deltas())


@pytest.mark.parametrize("family", unseen.FAMILIES)
def test_strength_zero_gives_the_mean_shape(family):
    assert np.allclose(_deform(family, 0.0), _dome(), atol=1e-12)


@pytest.mark.parametrize("family", unseen.FAMILIES)
def test_deterministic_finite_and_on_the_same_grid(family):
    a, b = _deform(family, 0.7), _deform(family, 0.7)
    other = _deform(family, 0.7, index=1)
    assert a.shape == _dome().shape and np.isfinite(a).all()
    assert np.array_equal(a, b)
    assert not np.allclose(a, other)  # another index is another deformation
    assert not np.allclose(a, _dome())


@pytest.mark.parametrize("family", unseen.FAMILIES)
def test_deformation_grows_with_strength(family):
    moves = [np.abs(_deform(family, s) - _dome()).max() for s in (0.25, 0.5, 1.0)]
    assert moves[0] < moves[1] < moves[2]


def test_rotation_is_rigid():
    a, b = _dome().reshape(-1, 3), _deform("rotation", 1.0).reshape(-1, 3)
    i = np.random.default_rng(1).integers(0, len(a), (200, 2))
    da = np.linalg.norm(a[i[:, 0]] - a[i[:, 1]], axis=1)
    db = np.linalg.norm(b[i[:, 0]] - b[i[:, 1]], axis=1)
    assert np.allclose(da, db, atol=1e-9)


def test_bending_a_flat_sheet_keeps_its_edge_lengths():
    """Bending is isometric on a plane (the sheet rolls onto a cylinder)."""
    flat = _dome()
    flat[..., 2] = 0.0
    bent = unseen.deform(flat, "bend", 1.0, 0)
    for axis in (0, 1):
        before = np.linalg.norm(np.diff(flat, axis=axis), axis=-1)
        after = np.linalg.norm(np.diff(bent, axis=axis), axis=-1)
        assert np.allclose(before, after, rtol=2e-3)
    assert np.abs(bent[..., 2]).max() > 0.3  # it left the plane


def test_twist_keeps_distances_to_its_axis_and_along_it():
    mean = _dome()
    rng = np.random.default_rng(stable_seed(0, "twist", 0))
    centre, axis = unseen._frame_axes(mean, rng)
    q0 = mean.reshape(-1, 3) - centre
    q1 = _deform("twist", 1.0).reshape(-1, 3) - centre
    along0, along1 = q0 @ axis, q1 @ axis
    assert np.allclose(along0, along1, atol=1e-9)
    radial = lambda q, t: np.linalg.norm(q - np.outer(t, axis), axis=1)  # noqa: E731
    assert np.allclose(radial(q0, along0), radial(q1, along1), atol=1e-9)


def test_normal_noise_moves_along_the_normals_within_its_amplitude():
    mean = _dome()
    moved = _deform("normal_noise", 1.0) - mean
    normals = grid_normals(mean)
    along = (moved * normals).sum(-1)
    assert np.allclose(moved, along[..., None] * normals, atol=1e-12)
    diag = np.linalg.norm(np.ptp(mean.reshape(-1, 3), axis=0))
    assert np.isclose(np.abs(along).max(), 0.08 * diag)


def test_extrapolation_needs_blendshapes():
    with pytest.raises(ValueError, match="blendshapes"):
        unseen.deform(_dome(), "extrapolation", 0.5, 0)
    assert unseen.families_for(False) == unseen.GEOMETRIC


def test_baselines():
    frames = np.stack([_dome(), _deform("bend", 0.5)])
    got = unseen.unshadowed_baseline(frames, 4)
    assert got.shape == (2, 16, 24, 24)
    want = unshadowed.diffuse(grid_normals(frames[1]), 4)
    assert np.allclose(np.moveaxis(got[1], 0, -1), want, atol=1e-6)
    mean_t = np.random.default_rng(2).normal(size=(16, 24, 24))
    static = unseen.static_baseline(mean_t, 3)
    assert static.shape == (3, 16, 24, 24) and np.allclose(static[2], mean_t, atol=1e-6)
