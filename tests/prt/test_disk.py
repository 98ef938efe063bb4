"""Meshes made by other libraries (trimesh.creation, PyVista sources) made disks and mapped."""

import numpy as np
import pytest
import pyvista as pv
import trimesh

from neurender.prt import disk
from neurender.prt import geometry_image as gi


def _pv(mesh: pv.PolyData) -> tuple[np.ndarray, np.ndarray]:
    mesh = mesh.triangulate().clean()
    return np.asarray(mesh.points, np.float64), mesh.faces.reshape(-1, 4)[:, 1:].astype(np.int64)


def _tm(mesh: trimesh.Trimesh) -> tuple[np.ndarray, np.ndarray]:
    return np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces, np.int64)


CLOSED = {
    "icosphere": (lambda: _tm(trimesh.creation.icosphere(3)), 0),
    "uv_sphere": (lambda: _tm(trimesh.creation.uv_sphere(count=[24, 24])), 0),
    "pv_ellipsoid": (lambda: _pv(pv.ParametricEllipsoid(1.0, 0.8, 0.7, u_res=30, v_res=30)), 0),
    "box": (lambda: _tm(trimesh.creation.box().subdivide().subdivide()), 0),
    "torus": (lambda: _tm(trimesh.creation.torus(1.0, 0.3)), 1),
    "pv_torus": (lambda: _pv(pv.ParametricTorus(1.0, 0.35, u_res=40, v_res=16)), 1),
}


@pytest.mark.parametrize("name", sorted(CLOSED))
def test_closed_surfaces_are_cut_and_map_without_flips(name):
    make, genus = CLOSED[name]
    vertices, faces = make()
    d = disk.to_disk(vertices, faces, name)
    assert d.changes["boundary_loops"] == 0 and d.changes["genus"] == genus
    assert disk.topology(d.faces) == (1, 0)  # one boundary loop, genus 0: a disk
    assert d.changes["seam_edges"] > 0 and 0 < d.changes["seam_length"] < 3
    # every disk vertex copies its source vertex
    np.testing.assert_array_equal(d.vertices, vertices[d.vertex_source])
    g = gi.build_geometry_image(d.vertices, d.faces, 24, d.anchors)
    assert g.flipped == 0
    # bijective onto the square: every triangle positive, together the square's area
    area = gi.signed_areas(g.uv, g.uv_faces)
    assert (area > 0).all() and area.sum() == pytest.approx(1.0)
    assert 1.0 <= g.stretch_l2 < 5.0, g.stretch_l2  # a cube has 8 cone points


def test_closed_surfaces_face_outward():
    """PyVista's ellipsoid winds its triangles inward; the disk's face outward."""
    vertices, faces = _pv(pv.ParametricEllipsoid(1.0, 0.8, 0.7, u_res=30, v_res=30))
    d = disk.to_disk(vertices, faces, "ellipsoid")
    p = d.vertices[d.faces]
    normals = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    assert ((normals * p.mean(1)).sum(1) > 0).all()
    assert d.changes["reoriented_faces"] == len(faces)


def test_torus_corners_at_the_cut_vertex():
    """A torus cut along two loops through one vertex is a rectangle: the square's corners
    are copies of the cut's branch vertices."""
    vertices, faces = _pv(pv.ParametricTorus(1.0, 0.35, u_res=40, v_res=16))
    d = disk.to_disk(vertices, faces, "torus")
    loop, bc = gi.pinned_boundary(d.vertices, d.faces, anchors=d.anchors)
    at_corner = loop[np.isin(bc, [0.0, 1.0]).all(1)]
    assert len(at_corner) == 4 and d.anchors[at_corner].all()


def test_annulus_is_cut_by_cut_to_disk():
    vertices, faces = _pv(pv.Cylinder(capping=False, resolution=24).triangulate().subdivide(2))
    d = disk.to_disk(vertices, faces, "tube")
    assert d.changes["boundary_loops"] == 2 and d.changes["seam_edges"] > 0
    g = gi.build_geometry_image(d.vertices, d.faces, 16, d.anchors)
    assert g.flipped == 0


def test_stl_style_triangle_soup_is_welded():
    """STL stores every triangle's own corners: welded back into one closed surface."""
    box = trimesh.creation.box().subdivide()
    soup = box.vertices[box.faces].reshape(-1, 3)
    d = disk.to_disk(soup, np.arange(len(soup)).reshape(-1, 3), "box.stl")
    assert d.changes["welded_vertices"] == len(soup) - len(box.vertices)
    assert d.changes["genus"] == 0 and d.changes["dropped_faces"] == 0


def test_doubled_and_collapsed_triangles_are_dropped():
    vertices, faces = _pv(pv.Plane(i_resolution=8, j_resolution=8))
    extra = np.array([faces[0], [faces[1][0], faces[1][0], faces[1][2]]])
    d = disk.to_disk(vertices, np.concatenate([faces, extra]), "plane")
    assert d.changes["dropped_faces"] == 2 and len(d.faces) == len(faces)


def test_mixed_winding_is_made_consistent_keeping_the_majority():
    vertices, faces = _pv(pv.Plane(i_resolution=10, j_resolution=10))
    flipped = faces.copy()
    flipped[::7] = flipped[::7][:, ::-1]
    d = disk.to_disk(vertices, flipped, "plane")
    assert d.changes["reoriented_faces"] == len(faces[::7])
    np.testing.assert_array_equal(np.sort(d.faces, 1), np.sort(faces, 1))
    p = d.vertices[d.faces]
    assert (np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])[:, 2] > 0).all()  # all like the plane's
    # a point resampled through the lift is the same point of the source triangle
    face, bary = d.lift(np.arange(len(d.faces)), np.full((len(d.faces), 3), 1 / 3))
    np.testing.assert_allclose(
        (vertices[flipped[face]] * bary[..., None]).sum(1), p.mean(1), atol=1e-12
    )


def test_several_components_are_refused_with_the_counts():
    a = trimesh.creation.icosphere(2)
    b = trimesh.creation.box()
    b.apply_translation([3, 0, 0])
    both = trimesh.util.concatenate([a, b])
    with pytest.raises(ValueError, match=r"mesh parts\.obj: 2 connected components \(320, 12"):
        disk.to_disk(both.vertices, both.faces, "parts.obj")


def test_non_manifold_edges_are_refused():
    vertices, faces = _pv(pv.Plane(i_resolution=4, j_resolution=4))
    fin = np.concatenate([vertices, [[0.0, 0.0, 1.0]]])
    edges, counts = np.unique(np.sort(disk.edges_of(faces), 1), axis=0, return_counts=True)
    a, b = edges[counts == 2][0]  # an interior edge gets a third triangle
    with pytest.raises(ValueError, match="1 edges are shared by more than two triangles"):
        disk.to_disk(fin, np.concatenate([faces, [[a, b, len(vertices)]]]), "fin")


def test_a_moebius_strip_is_refused():
    t = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    s = np.array([-0.3, 0.3])
    centre = np.stack([np.cos(t), np.sin(t), 0 * t], 1)
    half = t / 2
    offset = np.stack([np.cos(half) * np.cos(t), np.cos(half) * np.sin(t), np.sin(half)], 1)
    vertices = np.concatenate([centre + s[0] * offset, centre + s[1] * offset])
    n = len(t)
    faces = []
    for i in range(n):
        j = (i + 1) % n
        a, b, c, d = i, j, n + i, n + j
        if j == 0:  # the half twist joins each side to the other
            b, d = d, b
        faces += [[a, b, d], [a, d, c]]
    with pytest.raises(ValueError, match="not orientable"):
        disk.to_disk(vertices, np.array(faces), "moebius")
