import numpy as np
import pytest
import trimesh

from neurender import io
from neurender.display import srgb
from neurender.simplification import EXPORT_FILES, export, formats, mesh_ops


def test_export_writes_exactly_its_declared_files_and_the_obj_reloads(tmp_path):
    box = trimesh.creation.box()
    low = mesh_ops.uv_atlas(np.asarray(box.vertices), np.asarray(box.faces), 32)
    albedo = np.random.default_rng(0).uniform(0, 1, (32, 32, 3))
    flat = np.broadcast_to([0.5, 0.5, 1.0], albedo.shape)
    paths = {k: tmp_path / v for k, v in EXPORT_FILES.items()}
    export.export(paths, low, low.positions, albedo, flat, np.eye(4))
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(EXPORT_FILES.values())
    mesh = trimesh.load(tmp_path / EXPORT_FILES["obj"], process=False)
    assert len(mesh.faces) == len(low.uv_faces)
    np.testing.assert_allclose(mesh.vertices, low.positions[low.vmap], atol=1e-6)
    # OBJ counts v up the image, the stage (and glTF) down.
    np.testing.assert_allclose(1 - mesh.visual.uv[:, 1], low.uvs[:, 1], atol=1e-7)
    texture = np.asarray(mesh.visual.material.image.convert("RGB"))
    np.testing.assert_array_equal(texture, io.to_uint8(srgb(albedo)))


def test_lowpoly_keeps_the_albedo_and_the_map_to_the_assets_frame_only_when_given(tmp_path):
    box = trimesh.creation.box()
    low = mesh_ops.uv_atlas(np.asarray(box.vertices), np.asarray(box.faces), 16)
    formats.save_lowpoly(tmp_path / "builtin.npz", low, 0.8)
    assert "to_asset" not in io.load_npz(tmp_path / "builtin.npz")
    np.testing.assert_array_equal(formats.load_to_asset(tmp_path / "builtin.npz"), np.eye(4))
    assert formats.load_albedo(tmp_path / "builtin.npz") == 0.8
    to_asset = np.diag([2.0, 2.0, 2.0, 1.0])
    to_asset[:3, 3] = [1.0, -2.0, 3.0]
    formats.save_lowpoly(tmp_path / "user.npz", low, None, to_asset)
    np.testing.assert_array_equal(formats.load_to_asset(tmp_path / "user.npz"), to_asset)
    np.testing.assert_array_equal(formats.load_lowpoly(tmp_path / "user.npz").uvs, low.uvs)
    assert formats.load_albedo(tmp_path / "user.npz") is None  # the colour varies


def test_a_lowpoly_file_without_its_albedo_is_refused_by_name(tmp_path):
    box = trimesh.creation.box()
    low = mesh_ops.uv_atlas(np.asarray(box.vertices), np.asarray(box.faces), 16)
    io.save_npz(tmp_path / "old.npz", positions=low.positions, faces=low.faces)
    with pytest.raises(ValueError, match="old.npz has no albedo.*simplification_prepare"):
        formats.load_albedo(tmp_path / "old.npz")


def test_view_stacks_and_textures_round_trip(tmp_path):
    images = np.random.default_rng(1).uniform(0, 2, (3, 8, 8, 4)).astype(np.float32)
    formats.write_images(tmp_path / "v.exr", images)
    np.testing.assert_array_equal(formats.read_images(tmp_path / "v.exr"), images)
    texture = np.random.default_rng(2).uniform(0, 1, (16, 16, 3))
    formats.write_texture(tmp_path / "t.png", texture)
    np.testing.assert_allclose(formats.read_texture(tmp_path / "t.png"), texture, atol=0.5 / 65535)


def test_a_texture_as_stored_is_what_its_file_reads_back(tmp_path):
    texture = np.random.default_rng(3).uniform(-0.1, 1.1, (16, 16, 3))
    formats.write_texture(tmp_path / "t.png", texture)
    np.testing.assert_array_equal(formats.stored(texture), formats.read_texture(tmp_path / "t.png"))
