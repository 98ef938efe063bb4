"""Vertex counts from mesh headers equal what the mesh readers read, for files written by
trimesh and PyVista; formats without such a header say nothing."""

import pytest
import pyvista as pv
import trimesh

from neurender.mesh_header import vertex_count
from neurender.prt.objects import read_mesh


@pytest.mark.parametrize("suffix", [".obj", ".ply", ".off"])
@pytest.mark.parametrize(
    "mesh", [trimesh.creation.icosphere(2), trimesh.creation.torus(1.0, 0.3)], ids=["ball", "torus"]
)
def test_trimesh_files_declare_the_vertices_read(tmp_path, mesh, suffix):
    path = tmp_path / f"mesh{suffix}"
    mesh.export(path)
    assert vertex_count(path) == len(read_mesh(path)[0]) == len(mesh.vertices)


@pytest.mark.parametrize("binary", [True, False])
def test_pyvista_ply_and_obj_declare_the_vertices_read(tmp_path, binary):
    plane = pv.Plane(i_resolution=7, j_resolution=5).triangulate()
    plane.save(str(tmp_path / "plane.ply"), binary=binary)
    plane.save(str(tmp_path / "plane.obj"))
    for name in ("plane.ply", "plane.obj"):
        assert vertex_count(tmp_path / name) == len(read_mesh(tmp_path / name)[0]) == 48


def test_windows_line_ends_and_comments(tmp_path):
    (tmp_path / "a.obj").write_bytes(b"# exported\r\nv 0 0 0\r\nv 1 0 0\r\nvt 0 0\r\nv\t0 1 0\r\n")
    assert vertex_count(tmp_path / "a.obj") == 3
    (tmp_path / "a.off").write_text("OFF\n# comment\n\n4 2 0\n")
    assert vertex_count(tmp_path / "a.off") == 4
    (tmp_path / "b.off").write_text("OFF 5 1 0\n")
    assert vertex_count(tmp_path / "b.off") == 5


def test_other_formats_and_unreadable_files_say_nothing(tmp_path):
    trimesh.creation.box().export(tmp_path / "box.stl")
    trimesh.creation.box().export(tmp_path / "box.glb")
    assert vertex_count(tmp_path / "box.stl") is None
    assert vertex_count(tmp_path / "box.glb") is None
    assert vertex_count(tmp_path / "missing.ply") is None
    (tmp_path / "head.ply").write_text("ply\nformat ascii 1.0\nend_header\n")
    assert vertex_count(tmp_path / "head.ply") is None
