import numpy as np

from neurender.prt import deform, geometry_image


def test_bernstein_partition_of_unity():
    b = deform.bernstein(3, np.linspace(0, 1, 11))
    np.testing.assert_allclose(b.sum(-1), 1.0)


def test_undeformed_lattice_is_identity_and_moves_linearly():
    rng = np.random.default_rng(0)
    pts = rng.uniform(-1, 1, (50, 3))
    lo, hi = np.full(3, -1.0), np.full(3, 1.0)
    lattice = deform.ffd_lattice(lo, hi, (4, 3, 5))
    np.testing.assert_allclose(deform.ffd(pts, lo, hi, lattice), pts, atol=1e-12)
    shifted = deform.ffd(pts, lo, hi, lattice + np.array([0.1, 0, 0]))
    np.testing.assert_allclose(shifted - pts, np.broadcast_to([0.1, 0, 0], pts.shape), atol=1e-12)


def test_blendshapes_are_linear():
    rest = np.zeros((4, 4, 3))
    deltas = np.random.default_rng(1).normal(size=(2, 4, 4, 3))
    out = deform.apply_blendshapes(rest, deltas, np.array([[1.0, 0.0], [0.5, 2.0]]))
    np.testing.assert_allclose(out[0], deltas[0])
    np.testing.assert_allclose(out[1], 0.5 * deltas[0] + 2 * deltas[1])


def test_smooth_walk_stays_in_range_and_is_smooth():
    w = deform.smooth_walk(300, 5, np.random.default_rng(2))
    assert w.min() >= 0 and w.max() <= 1
    assert np.abs(np.diff(w, axis=0)).max() < 0.25


def test_cloth_keeps_pins_avoids_sphere_and_barely_stretches():
    uv = geometry_image.grid_uv(16)
    rest = np.column_stack([2 * uv - 1, np.zeros(len(uv))]).reshape(16, 16, 3)
    frames = deform.simulate_cloth(rest, 5, np.random.default_rng(0), sim_side=12, warmup=20)
    assert frames.shape == (5, 16, 16, 3) and np.isfinite(frames).all()
    # pinned far-edge corners stay at height 1
    np.testing.assert_allclose(frames[:, -1, 0, 1], 1.0, atol=1e-6)
    # the cloth has fallen and folded: not flat any more
    assert frames[-1, 0, :, 1].mean() < 0.5
    # edge lengths stay near their rest length (stretch constraints work)
    edge = np.linalg.norm(np.diff(frames[-1], axis=1), axis=-1)
    rest_edge = 2 / 15
    assert np.median(edge) < 1.15 * rest_edge
