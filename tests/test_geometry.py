import numpy as np
import pytest
import trimesh

from neurender.geometry import dot_components, grid_faces, grid_normals, vertex_normals
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
