"""Your objects for NDR: materials from the files other tools write (trimesh, PyVista),
normalisation, bad files named, and the maps they are rendered under."""

import math

import numpy as np
import pytest
import pyvista as pv
import trimesh
from PIL import Image

from neurender import asset_files
from neurender.asset_files import AssetFileError
from neurender.ndr import MESH_SUFFIXES, data, user_objects

DEFAULTS = {"base_colour": [0.8, 0.7, 0.6], "specular": 0.04, "roughness": 0.5}


def _srgb_decode(byte: int) -> float:
    x = byte / 255
    return x / 12.92 if x <= 0.04045 else ((x + 0.055) / 1.055) ** 2.4


def _glb(path, material, uv=None, mesh=None):
    mesh = mesh or trimesh.creation.icosphere(subdivisions=2, radius=3.0)
    mesh.visual = trimesh.visual.TextureVisuals(uv=uv, material=material)
    mesh.export(path)
    return path


def test_gltf_metallic_roughness_maps_to_the_two_lobes(tmp_path):
    material = trimesh.visual.material.PBRMaterial(
        baseColorFactor=[0.5, 0.25, 1.0, 1.0], metallicFactor=0.3, roughnessFactor=0.6
    )
    obj = user_objects.load_user_object(_glb(tmp_path / "ball.glb", material), DEFAULTS)
    base = np.array([128, 64, 255]) / 255  # glTF factors are linear; trimesh keeps 8 bits
    np.testing.assert_allclose(
        obj.albedo_diffuse, np.tile(base * 0.7 * 0.96, (len(obj.vertices), 1)), rtol=1e-5
    )
    np.testing.assert_allclose(obj.albedo_specular[0], 0.04 * 0.7 + base * 0.3, rtol=1e-5)
    np.testing.assert_allclose(obj.roughness, 0.6, rtol=1e-6)


@pytest.mark.parametrize(("metallic", "roughness"), [(1.0, 0.01), (0.0, 1.0)])
def test_pure_metal_and_pure_dielectric_limits(tmp_path, metallic, roughness):
    material = trimesh.visual.material.PBRMaterial(
        baseColorFactor=[0.9, 0.6, 0.2, 1.0], metallicFactor=metallic, roughnessFactor=roughness
    )
    obj = user_objects.load_user_object(_glb(tmp_path / "m.glb", material), DEFAULTS)
    base = np.array([230, 153, 51]) / 255
    if metallic:  # a metal: no diffuse lobe, its colour in the specular one
        np.testing.assert_allclose(obj.albedo_diffuse, 0)
        np.testing.assert_allclose(obj.albedo_specular[0], base, rtol=1e-5)
    else:  # a dielectric: grey F0 = 0.04
        np.testing.assert_allclose(obj.albedo_specular, 0.04, rtol=1e-5)
    # Roughness within the training objects' range [0.05, 1].
    assert obj.roughness.min() == pytest.approx(max(roughness, 0.05))


def test_base_colour_texture_is_sampled_at_the_vertices_and_decoded(tmp_path):
    """Left half of the texture red, right half blue; UVs from the vertex's x."""
    texture = np.zeros((8, 8, 3), np.uint8)
    texture[:, :4] = (200, 30, 30)
    texture[:, 4:] = (20, 40, 220)
    sphere = trimesh.creation.icosphere(subdivisions=2)
    x = sphere.vertices[:, 0]
    uv = np.column_stack([np.where(x < 0, 0.25, 0.75), np.full(len(x), 0.5)])
    material = trimesh.visual.material.PBRMaterial(
        baseColorTexture=Image.fromarray(texture), metallicFactor=0.0, roughnessFactor=0.5
    )
    obj = user_objects.load_user_object(_glb(tmp_path / "t.glb", material, uv, sphere), DEFAULTS)
    left = [_srgb_decode(c) * 0.96 for c in (200, 30, 30)]
    right = [_srgb_decode(c) * 0.96 for c in (20, 40, 220)]
    # Vertices keep their order; normalisation only moves and scales them.
    np.testing.assert_allclose(
        obj.albedo_diffuse[x < 0], np.tile(left, ((x < 0).sum(), 1)), rtol=1e-4
    )
    np.testing.assert_allclose(
        obj.albedo_diffuse[x > 0], np.tile(right, ((x > 0).sum(), 1)), rtol=1e-4
    )


def test_vertex_colours_of_a_pyvista_ply_are_decoded_and_defaults_fill_the_rest(tmp_path):
    surface = pv.Sphere(radius=2.0, center=(5, 0, 0), theta_resolution=16, phi_resolution=12)
    colours = np.zeros((surface.n_points, 3), np.uint8)
    colours[:, 0] = 255
    colours[:, 1] = np.arange(surface.n_points) % 256
    colours[:, 2] = 64
    surface.point_data["RGB"] = colours
    path = tmp_path / "coloured.ply"
    surface.save(str(path), texture="RGB")
    loaded = trimesh.load(path, process=False)
    obj = user_objects.load_user_object(path, DEFAULTS)
    expected = np.vectorize(_srgb_decode)(np.asarray(loaded.visual.vertex_colors)[:, :3])
    np.testing.assert_allclose(obj.albedo_diffuse, expected, rtol=1e-5, atol=1e-7)
    np.testing.assert_allclose(obj.albedo_specular, DEFAULTS["specular"])
    np.testing.assert_allclose(obj.roughness, DEFAULTS["roughness"])
    # Normalised like the procedural objects: centred box, farthest vertex at 1.
    v = obj.vertices.astype(np.float64)
    np.testing.assert_allclose((v.min(0) + v.max(0)) / 2, 0, atol=1e-6)
    assert np.linalg.norm(v, axis=1).max() == pytest.approx(1.0, abs=1e-6)


def test_a_vtk_file_reads_through_pyvista(tmp_path):
    path = tmp_path / "cone.vtp"
    pv.Cone(resolution=24).triangulate().save(str(path))
    obj = user_objects.load_user_object(path, DEFAULTS)
    assert len(obj.faces) > 20
    np.testing.assert_allclose(
        obj.albedo_diffuse, np.tile(DEFAULTS["base_colour"], (len(obj.vertices), 1))
    )


def test_obj_with_mtl_texture_and_a_missing_texture_named(tmp_path):
    box = trimesh.creation.box(extents=(2.0, 1.0, 1.0)).subdivide()
    uv = np.column_stack([box.vertices[:, 0] / 2 + 0.5, box.vertices[:, 1] + 0.5])
    texture = np.full((4, 4, 3), (40, 160, 90), np.uint8)
    box.visual = trimesh.visual.TextureVisuals(
        uv=uv, material=trimesh.visual.material.SimpleMaterial(image=Image.fromarray(texture))
    )
    text, files = trimesh.exchange.obj.export_obj(
        box, include_texture=True, mtl_name="box.mtl", return_texture=True
    )
    (tmp_path / "box.obj").write_text(text)
    for name, content in files.items():
        (tmp_path / name).write_bytes(content)
    named = [str(tmp_path / "box.obj"), *asset_files.asset_inputs(str(tmp_path / "box.obj"))]
    assert named[:2] == [str(tmp_path / "box.obj"), str(tmp_path / "box.mtl")] and len(named) == 3
    obj = user_objects.load_user_object(tmp_path / "box.obj", DEFAULTS)
    # The texture, not the MTL's Kd (trimesh writes 0.4), is the base colour.
    np.testing.assert_allclose(
        obj.albedo_diffuse[0], [_srgb_decode(c) for c in (40, 160, 90)], rtol=1e-4
    )
    texture_file = next(p for p in named if p.endswith(".png"))
    (tmp_path / texture_file).unlink()
    with pytest.raises(ValueError, match=r"box\.mtl names .*\.png .*, which does not exist"):
        user_objects.load_user_object(tmp_path / "box.obj", DEFAULTS)


def test_welded_normals_hide_uv_seams(tmp_path):
    """trimesh's UV sphere splits its seam; the shading normals are still radial there."""
    sphere = trimesh.creation.uv_sphere(radius=1.0, count=[16, 16])
    uv = np.column_stack(
        [np.arctan2(sphere.vertices[:, 0], sphere.vertices[:, 2]), sphere.vertices[:, 1]]
    )
    material = trimesh.visual.material.PBRMaterial(metallicFactor=0.0, roughnessFactor=0.4)
    obj = user_objects.load_user_object(_glb(tmp_path / "s.glb", material, uv, sphere), DEFAULTS)
    radial = obj.vertices / np.linalg.norm(obj.vertices, axis=1, keepdims=True)
    assert (np.sum(obj.normals * radial, axis=1) > 0.97).all()


def test_bad_meshes_are_refused_naming_the_file(tmp_path):
    with pytest.raises(ValueError, match=r"notes\.txt: unknown mesh format \.txt; expected one of"):
        user_objects.load_user_object(tmp_path / "notes.txt", DEFAULTS)
    with pytest.raises(ValueError, match=r"absent\.ply: no such file"):
        user_objects.load_user_object(tmp_path / "absent.ply", DEFAULTS)
    points = tmp_path / "points.ply"
    trimesh.PointCloud(np.random.default_rng(0).normal(size=(10, 3))).export(points)
    with pytest.raises(AssetFileError, match=r"points\.ply: no faces; found PointCloud of 10"):
        user_objects.load_user_object(points, DEFAULTS)
    flat = tmp_path / "point.obj"
    flat.write_text("v 1 1 1\nv 1 1 1\nv 1 1 1\nf 1 2 3\n")
    with pytest.raises(AssetFileError, match=r"point\.obj: degenerate bounding box"):
        user_objects.load_user_object(flat, DEFAULTS)
    broken = tmp_path / "nan.obj"
    broken.write_text("v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n")
    with pytest.raises(AssetFileError, match=r"nan\.obj: 1 of 3 vertices are not finite"):
        user_objects.load_user_object(broken, DEFAULTS)


CFG = {
    "seed": 3,
    "primitives": [2, 3],
    "edge_length": 0.3,
    "environment_height": 16,
    "user_probes_dir": "",
    "user_probe_fraction": 0.5,
    "small_sun_fraction": 0.3,
    "user_object_maps": 2,
    "test_samples": 3,
    "sunlit_samples": 1,
}


def test_user_objects_see_the_test_sets_own_maps():
    entries = user_objects.object_maps(CFG)
    assert [e.map_set for e in entries] == ["test maps"] * 2 + ["real-world-like maps"]
    for i in range(2):
        _, env, _, _ = data.sample_scene(CFG, "test", i)
        np.testing.assert_array_equal(entries[i].image, env)
    _, sunlit, name, _ = data.sample_scene(CFG, "sunlit_test", 0)
    assert name == "sunlit"
    np.testing.assert_array_equal(entries[2].image, sunlit)


def test_a_user_object_renders_as_a_test_sample(mitsuba):
    mi, _ = mitsuba
    cfg = {
        **CFG,
        "width": 16,
        "camera_distance": 3.9,
        "fov": 30.0,
        "coarse_height": 8,
        "coarse_shading": "importance",
        "coarse_samples": 16,
        "bright_texels": 16,
        "reference_spp": 16,
    }
    material = trimesh.visual.material.PBRMaterial(metallicFactor=0.0, roughnessFactor=0.5)
    mesh = trimesh.creation.annulus(r_min=0.3, r_max=1.0, height=0.6)
    mesh.visual = trimesh.visual.TextureVisuals(material=material)
    obj = user_objects.UserObject(
        vertices=np.asarray(mesh.vertices, np.float32),
        faces=np.asarray(mesh.faces, np.int32),
        albedo_diffuse=np.full((len(mesh.vertices), 3), 0.5, np.float32),
        albedo_specular=np.full((len(mesh.vertices), 3), 0.04, np.float32),
        roughness=np.full(len(mesh.vertices), 0.5, np.float32),
        n_primitives=1,
    )
    entry = user_objects.object_maps(cfg)[0]
    channels, light = user_objects.render_object(mi, cfg, "ring", obj, entry)
    again, _ = user_objects.render_object(mi, cfg, "ring", obj, entry)
    assert light.shape == (75,)
    for key in ("I_D.R", "S_S.G", "A_D.B", "mask"):
        np.testing.assert_array_equal(channels[key], again[key], err_msg=key)
    m = channels["mask"] > 0
    assert 0 < m.mean() < 1 and math.isfinite(float(channels["I_D.G"][m].mean()))


def test_the_config_check_names_missing_and_unreadable_objects(tmp_path):
    from pathlib import Path

    import yaml
    from snakemake.utils import update_config, validate

    from neurender import config as rules

    root = Path(__file__).resolve().parents[2]
    cfg = yaml.safe_load((root / "config/config.yaml").read_text())
    update_config(cfg, yaml.safe_load((root / "config/smoke.yaml").read_text()))
    validate(cfg, str(root / "workflow/schemas/config.schema.yaml"))
    (tmp_path / "a.obj").write_text("mtllib a.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    (tmp_path / "folder.obj").mkdir()
    (tmp_path / "notes.txt").write_text("a mesh, maybe\n")
    cfg["ndr"]["user_objects"] = {
        "gone": str(tmp_path / "gone.glb"),
        "folder": str(tmp_path / "folder.obj"),
        "text": str(tmp_path / "notes.txt"),
        "obj": str(tmp_path / "a.obj"),
        "made": "results/examples/vase.ply",
    }
    found = [p for p in rules.problems(cfg) if "user_objects" in p]
    assert found == [
        f"ndr.user_objects.gone = '{tmp_path / 'gone.glb'}': does not exist; expected a mesh "
        f"file NDR reads ({', '.join(MESH_SUFFIXES)})",
        f"ndr.user_objects.folder = '{tmp_path / 'folder.obj'}': is a folder, not a file; "
        f"expected a mesh file NDR reads ({', '.join(MESH_SUFFIXES)})",
        f"ndr.user_objects.text = '{tmp_path / 'notes.txt'}': expected a mesh file NDR reads "
        f"({', '.join(MESH_SUFFIXES)})",
        f"ndr.user_objects.obj = '{tmp_path / 'a.obj'}': {tmp_path / 'a.obj'} names a.mtl "
        f"({tmp_path / 'a.mtl'}), "
        "which does not exist",
    ]


def test_gltf_vertex_colours_are_linear(tmp_path):
    """glTF's COLOR_0 is linear (the specification), unlike the sRGB bytes of a PLY."""
    mesh = trimesh.creation.icosphere(subdivisions=1)
    colours = np.tile([200, 100, 50, 255], (len(mesh.vertices), 1)).astype(np.uint8)
    mesh.visual = trimesh.visual.ColorVisuals(mesh, vertex_colors=colours)
    mesh.export(tmp_path / "c.glb")
    obj = user_objects.load_user_object(tmp_path / "c.glb", DEFAULTS)
    np.testing.assert_allclose(obj.albedo_diffuse[0], np.array([200, 100, 50]) / 255, rtol=1e-6)
