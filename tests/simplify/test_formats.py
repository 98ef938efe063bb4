import numpy as np
import trimesh

from neurender.simplify import formats, mesh_ops


def test_textured_obj_writes_exactly_its_three_declared_files_and_reloads(tmp_path):
    box = trimesh.creation.box()
    low = mesh_ops.uv_atlas(np.asarray(box.vertices), np.asarray(box.faces), 32)
    albedo = np.random.default_rng(0).uniform(0, 1, (32, 32, 3))
    names = {"obj": "optimised.obj", "mtl": "optimised.mtl", "texture": "optimised_texture.png"}
    formats.write_obj({k: tmp_path / v for k, v in names.items()}, low, low.positions, albedo)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(names.values())
    mesh = trimesh.load(tmp_path / "optimised.obj", process=False)
    assert len(mesh.faces) == len(low.uv_faces)
    np.testing.assert_allclose(mesh.vertices, low.positions[low.vmap], atol=1e-6)
    texture = np.asarray(mesh.visual.material.image.convert("RGB"))
    np.testing.assert_array_equal(texture, np.round(albedo * 255).astype(np.uint8))


def test_view_stacks_and_textures_round_trip(tmp_path):
    images = np.random.default_rng(1).uniform(0, 2, (3, 8, 8, 4)).astype(np.float32)
    formats.write_images(tmp_path / "v.exr", images)
    np.testing.assert_array_equal(formats.read_images(tmp_path / "v.exr"), images)
    texture = np.random.default_rng(2).uniform(0, 1, (16, 16, 3))
    formats.write_texture(tmp_path / "t.png", texture)
    np.testing.assert_allclose(formats.read_texture(tmp_path / "t.png"), texture, atol=0.5 / 65535)
