import numpy as np
import pytest
import trimesh

from neurender.geometry import (
    dot_components,
    grid_faces,
    grid_normals,
    vertex_normals,
    winding_flips,
)
from neurender.prt import geometry_image as gi


def test_grid_faces_are_counter_clockwise_and_cover_the_square():
    uv = gi.grid_uv(5)
    faces = grid_faces(5)
    area = gi.signed_areas(uv, faces)
    assert (area > 0).all()
    assert area.sum() == pytest.approx(1.0)


def test_grid_normals_of_a_plane_point_up():
    uv = gi.grid_uv(6)
    p = np.column_stack([uv, np.zeros(len(uv))]).reshape(6, 6, 3)
    np.testing.assert_allclose(grid_normals(p), np.broadcast_to([0, 0, 1.0], (6, 6, 3)), atol=1e-12)


def test_vertex_normals_of_a_sphere_point_outwards():
    sphere = trimesh.creation.icosphere(subdivisions=3)
    n = vertex_normals(np.asarray(sphere.vertices), np.asarray(sphere.faces))
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-12)
    radial = sphere.vertices / np.linalg.norm(sphere.vertices, axis=1, keepdims=True)
    assert (np.einsum("ij,ij->i", n, radial) > 0.999).all()


def test_vertex_normals_weight_faces_by_area():
    # A vertex shared by a large triangle facing +z and a small one facing +x.
    v = np.array([[0, 0, 0], [2, 0, 0], [0, 2, 0], [0, 0.1, 0], [0, 0, -0.1]], float)
    faces = np.array([[0, 1, 2], [0, 3, 4]])
    n = vertex_normals(v, faces)[0]
    big, small = np.array([0, 0, 1.0]) * 2.0, np.array([-1.0, 0, 0]) * 0.005
    expected = (big + small) / np.linalg.norm(big + small)
    np.testing.assert_allclose(n, expected, atol=1e-12)


def test_dot_components_is_the_dot_product_of_the_vectors():
    rng = np.random.default_rng(5)
    a, b = rng.normal(size=(2, 4, 7, 3))
    got = dot_components(np.moveaxis(a, -1, 0), np.moveaxis(b, -1, 0))
    np.testing.assert_allclose(got, np.einsum("ijk,ijk->ij", a, b), atol=1e-12)


def _volume(positions, faces):
    p = positions[faces]
    return np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() / 6


def _flipped(faces, flip):
    return np.where(flip[:, None], faces[:, ::-1], faces)


def test_winding_flips_turn_an_inside_out_surface_outward_even_split_at_seams():
    sphere = trimesh.creation.icosphere(2)
    v, f = np.asarray(sphere.vertices), np.asarray(sphere.faces)
    assert not winding_flips(v, f)[0].any()
    mixed = f.copy()
    mixed[::3] = mixed[::3, ::-1]
    for faces in (f[:, ::-1], mixed):
        flip, closed = winding_flips(v, faces)
        assert closed.all()
        np.testing.assert_array_equal(_flipped(faces, flip), f)
    # Every triangle with its own corners (an STL): joined by position.
    split = v[f[:, ::-1]].reshape(-1, 3)
    own = np.arange(len(split)).reshape(-1, 3)
    flip, _ = winding_flips(split, own)
    assert flip.all() and _volume(split, _flipped(own, flip)) > 4


def test_winding_flips_leave_cavities_double_sided_sheets_and_moebius_strips():
    sphere = trimesh.creation.icosphere(2)
    v, f = np.asarray(sphere.vertices), np.asarray(sphere.faces)
    hollow_v = np.vstack([v, 0.5 * v])
    hollow_f = np.vstack([f, f[:, ::-1] + len(v)])
    assert not winding_flips(hollow_v, hollow_f)[0].any()
    quad = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0.0]])
    leaf = np.array([[0, 1, 2], [1, 3, 2], [2, 1, 0], [2, 3, 1]])
    assert not winding_flips(quad, leaf)[0].any()
    n = 24
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)[:, None]
    centre = np.column_stack([np.cos(t), np.sin(t), np.zeros_like(t)])
    across = 0.2 * (np.cos(t / 2) * centre + np.sin(t / 2) * np.array([0, 0, 1.0]))
    strip = np.vstack([centre + across, centre - across])
    faces = []
    for i in range(n - 1):
        faces += [[i, i + 1, n + i], [i + 1, n + i + 1, n + i]]
    faces += [[n - 1, n, 2 * n - 1], [n, 0, 2 * n - 1]]  # joined with a half twist
    faces = np.array(faces)
    faces[::4] = faces[::4, ::-1]
    assert not winding_flips(strip, faces)[0].any()


def test_winding_flips_give_an_open_surface_the_winding_of_most_of_its_triangles():
    sphere = trimesh.creation.icosphere(2)
    sphere.update_faces(sphere.triangles_center[:, 2] > 0)
    v, f = np.asarray(sphere.vertices), np.asarray(sphere.faces)
    for count in (7, len(f) - 7):  # a few triangles against the rest, either way
        faces = f.copy()
        faces[:count] = faces[:count, ::-1]
        flip, closed = winding_flips(v, faces)
        assert not closed.any()
        expected = f if count < len(f) / 2 else f[:, ::-1]
        np.testing.assert_array_equal(_flipped(faces, flip), expected)
