import numpy as np

from neurender import shapes
from neurender.prt import geometry_image as gi
from neurender.prt import objects


def _paraboloid(n_vertices=3000):
    pts, faces = shapes.disk_mesh(n_vertices, np.random.default_rng(0))
    z = 0.5 * (pts[:, 0] ** 2 + pts[:, 1] ** 2)
    return np.column_stack([pts, z]), faces


def test_paraboloid_geometry_image_reconstructs_surface():
    v, f = _paraboloid()
    g = gi.build_geometry_image(v, f, 32)
    assert g.flipped == 0
    grid = g.resample(f, v)
    assert grid.shape == (32, 32, 3)
    # every grid vertex lies on the paraboloid (up to the chord error of the source mesh)
    err = np.abs(grid[..., 2] - 0.5 * (grid[..., 0] ** 2 + grid[..., 1] ** 2))
    assert err.max() < 2e-3
    # the image border is the disk's boundary circle, corners included
    border = np.concatenate([grid[0], grid[-1], grid[:, 0], grid[:, -1]])
    np.testing.assert_allclose(np.linalg.norm(border[:, :2], axis=1), 1.0, atol=2e-3)
    err = gi.reconstruction_error(v, f, grid)
    assert err["mean"] < 5e-3 and err["max"] < 0.05


def test_boundary_square_corners_and_perimeter():
    angle = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    v = np.stack([np.cos(angle), np.sin(angle), 0 * angle], 1)
    sq = gi.boundary_square(v, np.arange(40))
    # on the perimeter, four corners hit exactly, uniform spacing by arc length
    on_edge = np.minimum.reduce([sq[:, 0], 1 - sq[:, 0], sq[:, 1], 1 - sq[:, 1]])
    np.testing.assert_allclose(on_edge, 0, atol=1e-12)
    for corner in gi._SQUARE_CORNERS:
        assert np.any(np.all(np.isclose(sq, corner), axis=1))
    steps = np.linalg.norm(np.diff(np.vstack([sq, sq[:1]]), axis=0), axis=1)
    np.testing.assert_allclose(steps, 0.1, atol=1e-9)


def test_builtin_objects_map_without_flips():
    for name in ("head", "creature", "cloth", "plane"):
        mesh = objects.source_mesh(name, 600, seed=0)
        g = gi.build_geometry_image(mesh.vertices, mesh.faces, 16)
        assert g.flipped == 0, name
