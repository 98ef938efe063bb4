import numpy as np
import pytest
import trimesh

from neurender import io
from neurender.asset_files import AssetFileError
from neurender.prt import data_jobs, objects
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


def _geometry_image(prt_params, tmp_path, path):
    """The geometry-image job of the user mesh ``mine`` at ``path``: its statistics."""
    config = {"prt": {"user_meshes": {"mine": str(path)}}}
    params = prt_params("prt_geometry_image", config, object="mine")
    out = {"gim": tmp_path / "gim.npz", "stats": tmp_path / "gim.csv"}
    data_jobs.prt_geometry_image({"source": str(path)}, out, params, 1)
    return io.read_csv(out["stats"]).set_index("metric")["value"]


@pytest.mark.parametrize("offset", [(0.0, 0.0, 0.0), (512345.0, 5412345.0, 230.0)])
def test_a_user_mesh_far_from_the_origin_is_warned_about_naming_file_and_key(
    tmp_path, caplog, prt_params, offset
):
    """A scan in georeferenced coordinates (UTM, metres): DeepPRT keeps positions in
    float32, 0.5 m apart at y ~ 5.4e6 m, so a 3 m creature would lose its shape."""
    mesh = objects.source_mesh("creature", 300, 0)
    path = tmp_path / "scan.obj"  # float64 digits, as a georeferenced export holds them
    lines = [f"v {x:.17g} {y:.17g} {z:.17g}" for x, y, z in mesh.vertices + offset]
    path.write_text("\n".join(lines + [f"f {a} {b} {c}" for a, b, c in mesh.faces + 1]))
    with caplog.at_level("WARNING", logger="neurender.prt.objects"):
        _geometry_image(prt_params, tmp_path, path)
    warned = [r.getMessage() for r in caplog.records if r.name == "neurender.prt.objects"]
    if offset[0] == 0:
        assert warned == []
    else:
        assert len(warned) == 1
        assert str(path) in warned[0] and "prt.user_meshes.mine" in warned[0]
        assert "5.41" in warned[0] and "float32" in warned[0]


@pytest.mark.parametrize(
    "make, genus",
    [(lambda: trimesh.creation.icosphere(1), 0), (lambda: _torus_with_a_hole(), 1)],
)
def test_closed_and_higher_genus_user_meshes_are_cut_to_a_disk(tmp_path, prt_params, make, genus):
    path = tmp_path / "mine.obj"
    make().export(path)
    stats = _geometry_image(prt_params, tmp_path, path)
    assert stats["flipped_triangles"] == 0 and stats["genus"] == genus
    assert stats["seam_length"] > 0


def test_user_mesh_with_several_components_is_refused_naming_the_file(tmp_path, prt_params):
    path = tmp_path / "bad.obj"
    _two_disks().export(path)
    with pytest.raises(ValueError, match=r"bad\.obj: 2 connected components"):
        _geometry_image(prt_params, tmp_path, path)


def test_user_mesh_format_and_missing_file(tmp_path, prt_params):
    with pytest.raises(AssetFileError, match=r"x\.fbx: unknown mesh format \.fbx; expected one"):
        objects.load_user_mesh(tmp_path / "x.fbx")
    with pytest.raises(AssetFileError, match=r"x\.obj: no such file"):
        objects.load_user_mesh(tmp_path / "x.obj")


def _torus_with_a_hole():
    """A torus (trimesh.creation) with one triangle removed: one component, one boundary
    loop, genus 1."""
    torus = trimesh.creation.torus(1.0, 0.3, major_sections=24, minor_sections=12)
    return trimesh.Trimesh(torus.vertices, torus.faces[1:])


@pytest.mark.parametrize("suffix", [".stl", ".obj"])
def test_a_one_triangle_user_mesh_is_refused_naming_the_file(tmp_path, prt_params, suffix):
    # An STL declares no vertex count, so only the job sees it; the OBJ's count is refused
    # by the dry run too (tests/prt/test_user_config.py).
    path = tmp_path / f"tri{suffix}"
    trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]]).export(path)
    with pytest.raises(ValueError) as info:
        _geometry_image(prt_params, tmp_path, path)
    message = str(info.value)
    assert f"mesh {path}: " in message
    assert "boundary loop has 3 vertices; expected at least 4" in message
    quad = tmp_path / f"quad{suffix}"
    square = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]
    trimesh.Trimesh(square, [[0, 1, 2], [0, 2, 3]]).export(quad)
    assert _geometry_image(prt_params, tmp_path, quad)["flipped_triangles"] == 0
