"""User assets made by other libraries (trimesh, PyVista) read with their materials, and
every kind of bad input refused with a message naming the file and what was found."""

import numpy as np
import pytest
import pyvista as pv
import trimesh
from PIL import Image

from neurender.asset_files import AssetFileError
from neurender.display import linear_from_srgb
from neurender.simplification import user_mesh


def random_texture(size=(16, 12), seed=0) -> np.ndarray:
    """An 8-bit ``(H, W, 3)`` texture (not square, so swapped axes show)."""
    return np.random.default_rng(seed).integers(0, 256, (*size, 3), dtype=np.uint8)


def texel_uvs(count: int, texture: np.ndarray, seed=1) -> tuple[np.ndarray, np.ndarray]:
    """Texture coordinates in trimesh's (OBJ's, v up) convention at random texel centres,
    and the ``(row, col)`` of each texel in the image (row 0 at the top)."""
    h, w = texture.shape[:2]
    rng = np.random.default_rng(seed)
    rows, cols = rng.integers(0, h, count), rng.integers(0, w, count)
    uv = np.column_stack([(cols + 0.5) / w, 1.0 - (rows + 0.5) / h])
    return uv, np.column_stack([rows, cols])


def textured_box(texture: np.ndarray, material=None) -> tuple[trimesh.Trimesh, np.ndarray]:
    box = trimesh.creation.box(extents=(1.0, 2.0, 0.5)).subdivide()
    uv, texels = texel_uvs(len(box.vertices), texture)
    material = material or trimesh.visual.material.PBRMaterial(
        baseColorTexture=Image.fromarray(texture)
    )
    box.visual = trimesh.visual.TextureVisuals(uv=uv, material=material)
    return box, texels


def corner_albedo(mesh: user_mesh.UserMesh) -> np.ndarray:
    """The loaded albedo at every face corner, ``(F, 3, 3)``, with the part's vertex index."""
    part = mesh.parts[0]
    faces = np.arange(len(part.faces))
    return np.stack(
        [mesh.albedo_at(faces, np.tile(np.eye(3)[k], (len(faces), 1))) for k in range(3)], 1
    )


def assert_albedo_is_the_files_texture(mesh, texture, texels, vertices_of_file):
    """Every face corner's albedo equals the decoded texel its vertex's UV points at."""
    part = mesh.parts[0]
    assert part.kind == "texture"
    # Match the loaded vertices to the written ones (a reader may reorder them).
    order = [int(np.argmin(np.linalg.norm(vertices_of_file - v, axis=1))) for v in part.vertices]
    rows, cols = texels[order].T
    expected = linear_from_srgb(texture[rows, cols] / 255.0)
    np.testing.assert_allclose(corner_albedo(mesh), expected[part.faces], atol=1e-6)


def test_textured_glb_reads_its_base_colour_texture_at_its_uvs(tmp_path):
    texture = random_texture()
    box, texels = textured_box(texture)
    box.export(tmp_path / "box.glb")
    mesh = user_mesh.load(tmp_path / "box.glb")
    assert len(mesh.parts) == 1 and len(mesh.faces) == len(box.faces)
    assert_albedo_is_the_files_texture(mesh, texture, texels, box.vertices)


def test_obj_with_mtl_reads_map_kd_at_its_uvs_and_ignores_kd(tmp_path):
    texture = random_texture(seed=3)
    material = trimesh.visual.material.SimpleMaterial(
        image=Image.fromarray(texture), diffuse=[100, 100, 100, 255], name="paint"
    )
    box, texels = textured_box(texture, material)
    text, files = trimesh.exchange.obj.export_obj(
        box, include_texture=True, mtl_name="box.mtl", return_texture=True
    )
    (tmp_path / "box.obj").write_text(text)
    for name, data in files.items():
        (tmp_path / name).write_bytes(data)
    mesh = user_mesh.load(tmp_path / "box.obj")
    np.testing.assert_array_equal(mesh.parts[0].albedo, 1.0)
    assert_albedo_is_the_files_texture(mesh, texture, texels, box.vertices)


def test_glb_base_colour_factor_multiplies_the_texture_in_linear_space(tmp_path):
    texture = random_texture(seed=4)
    factor = np.array([0.5, 1.0, 0.25, 1.0])
    material = trimesh.visual.material.PBRMaterial(
        baseColorTexture=Image.fromarray(texture), baseColorFactor=factor
    )
    box, _ = textured_box(texture, material)
    box.export(tmp_path / "box.glb")
    plain, _ = textured_box(texture)
    plain.export(tmp_path / "plain.glb")
    with_factor = corner_albedo(user_mesh.load(tmp_path / "box.glb"))
    without = corner_albedo(user_mesh.load(tmp_path / "plain.glb"))
    # trimesh keeps factors as 8-bit values: within half a step of 1/255.
    np.testing.assert_allclose(with_factor, without * factor[:3], atol=2.5e-3)


def test_scene_graph_is_flattened_with_node_transforms_and_materials(tmp_path):
    red = trimesh.creation.icosphere(2, radius=0.5)
    red.visual = trimesh.visual.TextureVisuals(
        material=trimesh.visual.material.PBRMaterial(baseColorFactor=[1.0, 0.0, 0.0, 1.0])
    )
    grey = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    shift = trimesh.transformations.translation_matrix([3.0, 0.0, 0.0])
    turn = trimesh.transformations.rotation_matrix(np.pi / 2, [0, 0, 1], [0, 2, 0])
    scene = trimesh.Scene()
    scene.add_geometry(red, node_name="a", transform=shift)
    scene.add_geometry(grey, node_name="b", transform=turn)
    scene.export(tmp_path / "scene.glb")
    mesh = user_mesh.load(tmp_path / "scene.glb")
    assert len(mesh.parts) == 2 and len(mesh.faces) == len(red.faces) + len(grey.faces)
    by_size = sorted(mesh.parts, key=lambda p: len(p.faces))
    np.testing.assert_allclose(
        by_size[0].vertices.mean(0), grey.apply_transform(turn).vertices.mean(0), atol=1e-6
    )
    np.testing.assert_allclose(by_size[1].vertices.mean(0), [3.0, 0.0, 0.0], atol=1e-6)
    np.testing.assert_allclose(by_size[1].albedo, [1.0, 0.0, 0.0], atol=1e-6)
    assert by_size[0].kind == by_size[1].kind == "constant"


def test_pyvista_ply_vertex_colours_are_decoded_from_srgb(tmp_path):
    sphere = pv.Sphere(theta_resolution=12, phi_resolution=8)
    colours = np.random.default_rng(5).integers(0, 256, (sphere.n_points, 3), dtype=np.uint8)
    sphere.point_data["RGB"] = colours
    sphere.save(str(tmp_path / "ball.ply"), texture="RGB")
    mesh = user_mesh.load(tmp_path / "ball.ply")
    part = mesh.parts[0]
    assert part.kind == "vertex"
    order = [int(np.argmin(np.linalg.norm(sphere.points - v, axis=1))) for v in part.vertices]
    np.testing.assert_allclose(part.vertex_colours, linear_from_srgb(colours[order] / 255.0))


def test_a_plain_mesh_is_grey_and_welded_across_split_vertices(tmp_path):
    box = trimesh.creation.box()
    box.unmerge_vertices()  # three copies of each corner, as exporters split seams
    box.export(tmp_path / "box.stl")
    mesh = user_mesh.load(tmp_path / "box.stl")
    assert mesh.parts[0].kind == "constant"
    np.testing.assert_allclose(mesh.parts[0].albedo, user_mesh.PLAIN_ALBEDO)
    assert len(mesh.vertices) == 8 and len(mesh.faces) == 12


def test_mitsuba_reference_shows_the_albedo_the_baker_reads(mitsuba, tmp_path):
    """Rays through Mitsuba's reference meshes return the albedo ``albedo_at`` gives at
    the same surface point: textured (orientation of rows and v), vertex and face colours."""
    mi, _ = mitsuba
    texture = random_texture((8, 8), seed=6)
    quad = trimesh.Trimesh(
        [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], [[0, 1, 2], [0, 2, 3]], process=False
    )
    quad.visual = trimesh.visual.TextureVisuals(
        uv=[[0, 0], [1, 0], [1, 1], [0, 1]],
        material=trimesh.visual.material.PBRMaterial(baseColorTexture=Image.fromarray(texture)),
    )
    quad.export(tmp_path / "quad.glb")
    coloured = quad.copy()
    coloured.visual = trimesh.visual.ColorVisuals(
        quad, vertex_colors=[[255, 0, 0, 255], [0, 255, 0, 255], [0, 0, 255, 255], [9, 9, 9, 255]]
    )
    coloured.export(tmp_path / "quad.ply")
    faces_coloured = quad.copy()
    faces_coloured.visual = trimesh.visual.ColorVisuals(
        quad, face_colors=[[255, 128, 0, 255], [0, 64, 255, 255]]
    )
    faces_coloured.export(tmp_path / "faces.ply")
    xy = np.random.default_rng(7).uniform(-0.95, 0.95, (20, 2))
    for name in ("quad.glb", "quad.ply", "faces.ply"):
        mesh = user_mesh.load(tmp_path / name)
        scene = mi.load_dict({"type": "scene", "shape": mesh.mitsuba_shapes(mi)[0]})
        rays = mi.Ray3f(
            o=mi.Point3f(xy[:, 0], xy[:, 1], np.full(len(xy), 2.0)), d=mi.Vector3f(0, 0, -1)
        )
        si = scene.ray_intersect(rays)
        seen = np.array(si.bsdf().eval_diffuse_reflectance(si)).T
        v = mesh.vertices
        faces = np.where(xy[:, 0] > xy[:, 1], 0, 1)  # (0, 1, 2) below the diagonal
        tri = v[mesh.faces[faces]][:, :, :2]
        bary = np.stack(
            [
                np.linalg.solve(np.vstack([t.T, np.ones(3)]), np.append(p, 1.0))
                for t, p in zip(tri, xy, strict=True)
            ]
        )
        np.testing.assert_allclose(seen, mesh.albedo_at(faces, bary), atol=2e-5, err_msg=name)


def write_obj(path, lines, mtl=None):
    path.write_text("\n".join(lines) + "\n")
    if mtl is not None:
        path.with_suffix(".mtl").write_text("\n".join(mtl) + "\n")


TRIANGLE = ["v 0 0 0", "v 1 0 0", "v 0 1 0", "f 1 2 3"]


@pytest.mark.parametrize(
    ("lines", "found"),
    [
        (["v 0 0 0", "v 1 0 0", "v 0 1 0"], "no faces; found PointCloud of 3 vertices"),
        (["v 0 0 0", "v 1 0 0", "v nan 1 0", "f 1 2 3"], "1 of 3 vertices are not finite"),
        (["v 0 0 0", "v 1 0 0", "v 2 0 0", "f 1 2 3"], "degenerate bounding box"),
        (["v 1 1 1", "v 1 1 1", "v 1 1 1", "f 1 2 3"], "degenerate bounding box"),
        (["hello"], "no faces; found no geometry"),
    ],
)
def test_bad_geometry_is_refused_naming_the_file(tmp_path, lines, found):
    write_obj(tmp_path / "bad.obj", lines)
    with pytest.raises(AssetFileError, match=found) as err:
        user_mesh.load(tmp_path / "bad.obj")
    assert str(tmp_path / "bad.obj") in str(err.value)


def test_a_missing_texture_is_named_with_the_mtl_that_names_it(tmp_path):
    mtl = ["newmtl paint", "Kd 1 1 1", "map_Kd -s 1 1 1 textures/wood grain.png"]
    write_obj(tmp_path / "crate.obj", ["mtllib crate.mtl", "usemtl paint", *TRIANGLE], mtl)
    with pytest.raises(AssetFileError) as err:
        user_mesh.load(tmp_path / "crate.obj")
    message = str(err.value)
    assert str(tmp_path / "crate.mtl") in message
    assert str(tmp_path / "textures" / "wood grain.png") in message and "does not exist" in message


def test_a_missing_mtl_and_missing_gltf_resources_are_named(tmp_path):
    write_obj(tmp_path / "a.obj", ["mtllib gone.mtl", *TRIANGLE])
    with pytest.raises(AssetFileError, match="names gone.mtl"):
        user_mesh.load(tmp_path / "a.obj")
    trimesh.creation.box().export(tmp_path / "box.gltf")
    buffers = sorted(tmp_path.glob("*.bin"))
    buffers[0].unlink()
    with pytest.raises(AssetFileError, match=f"names {buffers[0].name}"):
        user_mesh.load(tmp_path / "box.gltf")


def test_an_unreadable_file_an_unknown_format_and_no_file_are_refused(tmp_path):
    (tmp_path / "junk.glb").write_bytes(b"not a glb at all" * 4)
    with pytest.raises(AssetFileError, match=r"junk.glb: could not be read as GLB"):
        user_mesh.load(tmp_path / "junk.glb")
    (tmp_path / "mesh.fbx").write_bytes(b"")
    with pytest.raises(AssetFileError, match=r"unknown mesh format .fbx; expected one of"):
        user_mesh.load(tmp_path / "mesh.fbx")
    with pytest.raises(AssetFileError, match=r"gone.ply: no such file"):
        user_mesh.load(tmp_path / "gone.ply")


def test_an_unreadable_texture_is_refused_not_dropped(tmp_path):
    lines = ["mtllib a.mtl", "v 0 0 0", "v 1 0 0", "v 0 1 0", "vt 0 0", "vt 1 0", "vt 0 1"]
    lines += ["usemtl m", "f 1/1 2/2 3/3"]
    write_obj(tmp_path / "a.obj", lines, ["newmtl m", "map_Kd a.png"])
    (tmp_path / "a.png").write_text("not an image")
    with pytest.raises(AssetFileError) as err:
        user_mesh.load(tmp_path / "a.obj")
    assert str(err.value).startswith(
        f"{tmp_path / 'a.obj'}: {tmp_path / 'a.mtl'} names a.png ({tmp_path / 'a.png'}), which "
        "could not be read: it cannot be decoded (UnidentifiedImageError"
    )
