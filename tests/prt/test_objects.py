import numpy as np
import pytest
import trimesh

from neurender.prt import objects
from neurender.shapes import BLENDSHAPES


def _two_disks():
    m = objects.source_mesh("creature", 300, 0)
    v = np.concatenate([m.vertices, m.vertices + [5.0, 0, 0]])
    return trimesh.Trimesh(v, np.concatenate([m.faces, m.faces + len(m.vertices)]), process=False)


def test_head_has_blendshapes_and_is_deterministic():
    a = objects.source_mesh("head", 800, seed=3)
    b = objects.source_mesh("head", 800, seed=3)
    np.testing.assert_array_equal(a.vertices, b.vertices)
    assert set(a.blendshapes) == set(BLENDSHAPES) and len(a.blendshapes) >= 6
    assert all(np.abs(d).max() > 0.02 for d in a.blendshapes.values())


def test_plane_shares_the_head_triangulation():
    head, plane = objects.source_mesh("head", 800, 1), objects.source_mesh("plane", 800, 1)
    np.testing.assert_array_equal(head.faces, plane.faces)
    np.testing.assert_array_equal(head.vertices[:, :2], plane.vertices[:, :2])
    assert (plane.vertices[:, 2] == 0).all()


def test_user_mesh_disk_is_accepted(tmp_path):
    mesh = objects.source_mesh("creature", 500, 0)
    path = tmp_path / "disk.ply"
    trimesh.Trimesh(mesh.vertices, mesh.faces).export(path)
    loaded = objects.load_user_mesh(path)
    assert len(loaded.faces) == len(mesh.faces)


@pytest.mark.parametrize(
    "make, message",
    [
        (lambda: trimesh.creation.icosphere(1), "0 boundary loops"),
        (lambda: _two_disks(), "2 connected components"),
        (lambda: _torus_with_a_hole(), "V - E \\+ F = .* = -1, so genus 1"),
    ],
)
def test_user_mesh_errors_name_file_and_finding(tmp_path, make, message):
    path = tmp_path / "bad.obj"
    make().export(path)
    with pytest.raises(ValueError, match=message) as info:
        objects.load_user_mesh(path)
    assert "bad.obj" in str(info.value)


def test_user_mesh_format_and_missing_file(tmp_path):
    with pytest.raises(ValueError, match="unsupported format"):
        objects.load_user_mesh(tmp_path / "x.fbx")
    with pytest.raises(FileNotFoundError, match="x.obj"):
        objects.load_user_mesh(tmp_path / "x.obj")


def _torus_with_a_hole():
    """A torus (trimesh.creation) with one triangle removed: one component, one boundary
    loop, genus 1."""
    torus = trimesh.creation.torus(1.0, 0.3, major_sections=24, minor_sections=12)
    return trimesh.Trimesh(torus.vertices, torus.faces[1:])
