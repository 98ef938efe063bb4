import numpy as np
import pytest
import pyvista as pv

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


def test_perimeter_points_hit_the_corners_and_space_by_arc_length():
    angle = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    v = np.stack([np.cos(angle), np.sin(angle), 0 * angle], 1)
    sq = gi.perimeter_points(v, np.arange(40))
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


def _pv_disk(surface):
    mesh = surface.triangulate().clean()
    return np.asarray(mesh.points, np.float64), mesh.faces.reshape(-1, 4)[:, 1:].astype(np.int64)


def test_third_party_disk_with_boundary_ears_maps_without_flips():
    """PyVista's random hills (14,400 vertices, a valid disk) have a triangle with all three
    corners on one side of the square: the corner-pinned map flattens it even with uniform
    weights (the reported failure). Splitting that interior edge makes the map bijective."""
    v, f = _pv_disk(pv.ParametricRandomHills(u_res=120, v_res=120))
    assert len(v) == 14400
    objects.check_disk_topology(v, f, "hills")
    _, method, flipped = gi.harmonic_square_map(v, f)
    assert (method, flipped) == ("uniform", 1)  # reproduces the failure without the repair
    loop, bc = gi.pinned_boundary(v, f)
    assert len(gi.same_side_edges(f, loop, bc)) == 1
    g = gi.build_geometry_image(v, f, 64)
    assert g.flipped == 0 and g.split_edges == 1
    area = gi.signed_areas(g.uv, g.uv_faces)
    assert (area > 0).all() and area.sum() == pytest.approx(1.0)
    # the lookup is in the input's triangles: grid points lie on the surface
    err = gi.reconstruction_error(v, f, g.resample(f, v))
    assert err["mean"] < 2e-3


@pytest.mark.parametrize(
    "surface",
    [
        pv.ParametricCatalanMinimal,  # repeated vertices: zero-length boundary edges
        pv.ParametricHenneberg,
        pv.ParametricDini,
        pv.ParametricBour,
    ],
)
def test_other_third_party_disks_map_without_flips(surface):
    v, f = _pv_disk(surface(u_res=60, v_res=60))
    g, d = gi.parametrise(v, f, 16, surface.__name__)
    assert g.flipped == 0
    area = gi.signed_areas(g.uv, g.uv_faces)
    assert (area > 0).all()


def test_split_edges_keeps_the_surface_and_its_lookup():
    """Splitting an edge puts its midpoint on the surface; a point of a new triangle is the
    same point of its source triangle."""
    v, f = _pv_disk(pv.Plane(i_resolution=3, j_resolution=3))
    edges, counts = np.unique(
        np.sort(f[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), 1), axis=0, return_counts=True
    )
    inner = edges[counts == 2][:3]
    v2, f2, parent, corners = gi.split_edges(v, f, inner)
    assert len(v2) == len(v) + 3 and len(f2) == len(f) + 6
    np.testing.assert_allclose(v2[len(v) :], v[inner].mean(1))
    rng = np.random.default_rng(0)
    bary = rng.dirichlet([1, 1, 1], len(f2))
    point = (v2[f2] * bary[..., None]).sum(1)
    lifted = np.einsum("pk,pkc->pc", bary, corners)
    np.testing.assert_allclose((v[f[parent]] * lifted[..., None]).sum(1), point, atol=1e-12)


def test_stretch_is_one_for_isometry_and_analytic_for_a_scaled_map():
    v, f = _pv_disk(pv.Plane(i_resolution=6, j_resolution=6))
    uv = v[:, :2] + 0.5
    assert gi.stretch(v, f, uv) == pytest.approx({"l2": 1.0, "max": 1.0})
    # surface = (2u, v): singular values 2 and 1; normalised by sqrt(planar / surface area)
    s = gi.stretch(np.column_stack([2 * uv[:, 0], uv[:, 1], 0 * uv[:, 0]]), f, uv)
    assert s["l2"] == pytest.approx(np.sqrt(2.5) / np.sqrt(2))
    assert s["max"] == pytest.approx(2 / np.sqrt(2))
