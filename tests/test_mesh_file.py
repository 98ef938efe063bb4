"""The one reader of a user's mesh file, through every method's loader, on files made by
other tools (trimesh, PyVista, Pillow, a glTF written by hand) and laid out as users lay
them out: textures found by one rule or refused by name, indices checked, one v convention."""

import base64
import json
import logging
import os
import shutil
import struct
import sys

import numpy as np
import pytest
import pyvista as pv
import trimesh
from PIL import Image

from neurender import asset_files, mesh_file, user_paths
from neurender.asset_files import AssetFileError
from neurender.display import linear_from_srgb
from neurender.ndr import user_objects
from neurender.prt import objects
from neurender.simplification import user_mesh

DEFAULTS = {"base_colour": [0.8, 0.7, 0.6], "specular": 0.04, "roughness": 0.5}
LOADERS = {
    "prt": objects.read_mesh,
    "ndr": lambda path: user_objects.load_user_object(path, DEFAULTS),
    "simplification": user_mesh.load,
}
#: Texel grid of :func:`gridded_box`: one row per y value, one column per two x values.
ROWS, COLS = 5, 3


def gridded_box() -> tuple[trimesh.Trimesh, np.ndarray]:
    """A box whose every vertex's UV is the centre of texel ``(row, col)`` = (index of its
    y, half the index of its x) in a ``(ROWS, COLS)`` texture (trimesh's v-up coordinates), so a
    loaded vertex's expected colour follows from its position alone; and the texture."""
    box = trimesh.creation.box(extents=(1.0, 2.0, 0.5)).subdivide().subdivide()
    col = np.unique(box.vertices[:, 0].round(6), return_inverse=True)[1].ravel() // 2
    row = np.unique(box.vertices[:, 1].round(6), return_inverse=True)[1].ravel()
    assert col.max() + 1 == COLS and row.max() + 1 == ROWS
    uv = np.column_stack([(col + 0.5) / COLS, 1.0 - (row + 0.5) / ROWS])
    texture = np.random.default_rng(0).integers(0, 256, (ROWS, COLS, 3), dtype=np.uint8)
    box.visual = trimesh.visual.TextureVisuals(
        uv=uv, material=trimesh.visual.material.SimpleMaterial(image=Image.fromarray(texture))
    )
    return box, texture


def expected_colours(vertices: np.ndarray, texture: np.ndarray) -> np.ndarray:
    """The decoded texel of each vertex of a (moved, uniformly scaled) :func:`gridded_box`."""
    col = np.unique(vertices[:, 0].round(5), return_inverse=True)[1].ravel() // 2
    row = np.unique(vertices[:, 1].round(5), return_inverse=True)[1].ravel()
    return linear_from_srgb(texture[row, col] / 255.0)


def write_obj(folder, mesh, name="box") -> dict:
    """``mesh`` as OBJ + MTL + PNG by trimesh's exporter into ``folder``; the files by kind."""
    folder.mkdir(parents=True, exist_ok=True)
    text, files = trimesh.exchange.obj.export_obj(
        mesh, include_texture=True, mtl_name=f"{name}.mtl", return_texture=True
    )
    (folder / f"{name}.obj").write_text(text)
    for file, data in files.items():
        (folder / file).write_bytes(data)
    png = next(f for f in files if f.endswith(".png"))
    return {"obj": folder / f"{name}.obj", "mtl": folder / f"{name}.mtl", "png": folder / png}


def assert_texture_loaded(path, texture):
    """NDR's vertex albedo and the simplification's corner albedo are the texels."""
    obj = user_objects.load_user_object(path, DEFAULTS)
    np.testing.assert_allclose(
        obj.albedo_diffuse, expected_colours(obj.vertices, texture), atol=1e-6
    )
    mesh = user_mesh.load(path)
    part = mesh.parts[0]
    assert part.kind == "texture"
    faces = np.arange(len(part.faces))
    for k in range(3):
        seen = mesh.albedo_at(faces, np.tile(np.eye(3)[k], (len(faces), 1)))
        want = expected_colours(part.vertices, texture)[part.faces[:, k]]
        np.testing.assert_allclose(seen, want, atol=1e-6)
    vertices, faces = objects.read_mesh(path)
    assert len(faces) == len(obj.faces) and np.isfinite(vertices).all()


def test_obj_mtl_png_as_symbolic_links_into_another_folder(tmp_path):
    box, texture = gridded_box()
    files = write_obj(tmp_path / "library", box)
    mine = tmp_path / "project"
    mine.mkdir()
    for path in files.values():
        os.symlink(path, mine / path.name)
    # trimesh alone refuses the links (they resolve outside the folder) and says nothing.
    loaded = trimesh.load(mine / "box.obj", force="scene", process=False)
    assert next(iter(loaded.geometry.values())).visual.material.image.size == (2, 2)
    assert asset_files.missing(mine / "box.obj") == []
    assert_texture_loaded(mine / "box.obj", texture)


def test_an_mtl_naming_a_texture_in_a_sibling_folder(tmp_path):
    box, texture = gridded_box()
    files = write_obj(tmp_path / "asset", box)
    (tmp_path / "textures").mkdir()
    shutil.move(files["png"], tmp_path / "textures" / "wood.png")
    text = (
        files["mtl"]
        .read_text()
        .replace(f"map_Kd {files['png'].name}", "map_Kd ../textures/wood.png")
    )
    files["mtl"].write_text(text)
    assert asset_files.asset_inputs(str(files["obj"])) == sorted(
        [str(files["mtl"]), str(tmp_path / "asset" / ".." / "textures" / "wood.png")]
    )
    assert_texture_loaded(files["obj"], texture)


def test_an_mtl_in_another_folder_names_textures_relative_to_itself(tmp_path):
    """The rule is relative to the file that names it: the MTL, not the OBJ."""
    box, texture = gridded_box()
    files = write_obj(tmp_path / "asset", box)
    (tmp_path / "asset" / "materials").mkdir()
    shutil.move(files["mtl"], tmp_path / "asset" / "materials" / "box.mtl")
    shutil.move(files["png"], tmp_path / "asset" / "materials" / files["png"].name)
    files["obj"].write_text(
        files["obj"].read_text().replace("mtllib box.mtl", "mtllib materials/box.mtl")
    )
    assert_texture_loaded(files["obj"], texture)


def _broken_texture(tmp_path, damage):
    box, _ = gridded_box()
    files = write_obj(tmp_path, box)
    damage(files["png"])
    return files


@pytest.mark.parametrize("method", ["ndr", "simplification"])
@pytest.mark.parametrize(
    ("damage", "reason"),
    [
        (lambda p: p.write_bytes(b"\x89PNG\r\n\x1a\n not really"), "it cannot be decoded"),
        (lambda p: p.write_bytes(p.read_bytes()[:60]), "it cannot be decoded"),
        (lambda p: p.unlink(), "does not exist"),
        (lambda p: (p.unlink(), p.mkdir()), "is a folder, not a file"),
    ],
    ids=["corrupt", "truncated", "missing", "folder"],
)
def test_a_texture_named_but_not_loaded_is_an_error_naming_mtl_texture_and_reason(
    tmp_path, method, damage, reason
):
    files = _broken_texture(tmp_path, damage)
    with pytest.raises(AssetFileError) as err:
        LOADERS[method](files["obj"])
    message = str(err.value)
    assert message.startswith(f"{files['obj']}: {files['mtl']} names {files['png'].name} ")
    assert reason in message and str(files["png"]) in message


def test_a_texture_over_pillows_pixel_limit_is_refused_in_every_method(tmp_path, monkeypatch):
    box, _ = gridded_box()
    files = write_obj(tmp_path, box)
    monkeypatch.setattr(Image, "MAX_IMAGE_PIXELS", 10)  # the texture has 15 pixels
    for method in ("ndr", "simplification"):
        with pytest.raises(AssetFileError, match="over Pillow's pixel limit") as err:
            LOADERS[method](files["obj"])
        assert f"{files['mtl']} names {files['png'].name}" in str(err.value)
        assert "MAX_IMAGE_PIXELS = 10" in str(err.value)
    objects.read_mesh(files["obj"])  # DeepPRT reads the geometry only


def _quad_gltf(folder, image: str):
    """A unit quad in z = 0 as a hand-written ``.gltf`` (no trimesh): top vertices (y = 1)
    at glTF ``v = 0.25``, bottom ones at ``v = 0.75`` (glTF's ``v`` points down the image);
    a texture named ``image``, metallic 0."""
    positions = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float32)
    uvs = np.array([[0.5, 0.75], [0.5, 0.75], [0.5, 0.25], [0.5, 0.25]], np.float32)
    indices = np.array([0, 1, 2, 0, 2, 3], np.uint16)
    blob = positions.tobytes() + uvs.tobytes() + indices.tobytes()
    views = [(0, 48), (48, 32), (80, 12)]
    tree = {
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [
            {
                "primitives": [
                    {"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": 2, "material": 0}
                ]
            }
        ],
        "materials": [
            {"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0.0}}
        ],
        "textures": [{"source": 0}],
        "images": [{"uri": image}],
        "buffers": [
            {
                "byteLength": len(blob),
                "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode(),
            }
        ],
        "bufferViews": [{"buffer": 0, "byteOffset": o, "byteLength": n} for o, n in views],
        "accessors": [
            {
                "bufferView": 0,
                "componentType": 5126,
                "count": 4,
                "type": "VEC3",
                "min": [-1, -1, 0],
                "max": [1, 1, 0],
            },
            {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"},
            {"bufferView": 2, "componentType": 5123, "count": 6, "type": "SCALAR"},
        ],
    }
    path = folder / "quad.gltf"
    path.write_text(json.dumps(tree))
    return path


RED, BLUE = (220, 20, 30), (10, 40, 230)


def _top_red_texture(path):
    """A 1 x 2 PNG by Pillow: its top row red, its bottom row blue."""
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(np.array([[RED], [BLUE]], np.uint8)).save(path)


@pytest.mark.parametrize("fmt", ["gltf", "obj"])
def test_one_v_convention_puts_the_top_of_the_image_on_top(tmp_path, fmt):
    """glTF counts v down the image, OBJ up: a quad whose top vertices point at the top
    half of a red-over-blue texture is red on top in both methods, from either format."""
    if fmt == "gltf":
        _top_red_texture(tmp_path / "textures" / "paint.png")
        (tmp_path / "model").mkdir()
        path = _quad_gltf(tmp_path / "model", "../textures/paint.png")
        scale = 1 - 0.04  # NDR's dielectric diffuse lobe of a glTF material
    else:
        _top_red_texture(tmp_path / "paint.png")
        (tmp_path / "quad.mtl").write_text("newmtl paint\nmap_Kd paint.png\n")
        lines = ["mtllib quad.mtl", "v -1 -1 0", "v 1 -1 0", "v 1 1 0", "v -1 1 0"]
        lines += ["vt 0.5 0.25", "vt 0.5 0.75", "usemtl paint", "f 1/1 2/1 3/2", "f 1/1 3/2 4/2"]
        path = tmp_path / "quad.obj"
        path.write_text("\n".join(lines) + "\n")
        scale = 1.0
    red, blue = linear_from_srgb(np.array([RED, BLUE]) / 255.0)
    obj = user_objects.load_user_object(path, DEFAULTS)
    top = obj.vertices[:, 1] > 0
    np.testing.assert_allclose(obj.albedo_diffuse[top], np.tile(red * scale, (2, 1)), rtol=1e-5)
    np.testing.assert_allclose(obj.albedo_diffuse[~top], np.tile(blue * scale, (2, 1)), rtol=1e-5)
    mesh = user_mesh.load(path)
    part = mesh.parts[0]
    corners = np.eye(3)[np.argmax(part.vertices[part.faces][:, :, 1], axis=1)]
    np.testing.assert_allclose(
        mesh.albedo_at(np.arange(2), corners), np.tile(red, (2, 1)), atol=1e-6
    )


def test_sample_bilinear_repeats_and_hits_texel_centres():
    texture = np.arange(4 * 3 * 3, dtype=float).reshape(4, 3, 3)
    centres = np.array([[0.5 / 3, 0.5 / 4], [2.5 / 3, 3.5 / 4], [1 + 1.5 / 3, -1 + 2.5 / 4]])
    np.testing.assert_allclose(
        mesh_file.sample_bilinear(texture, centres), texture[[0, 3, 2], [0, 2, 1]]
    )
    # Half-way between the last and the first column wraps around.
    edge = mesh_file.sample_bilinear(texture, np.array([[1.0, 0.5 / 4]]))
    np.testing.assert_allclose(edge[0], (texture[0, 0] + texture[0, 2]) / 2)
    # trimesh's v up: its v = 1 - 0.5/4 is the top row's centre.
    top = mesh_file.sample_bilinear(texture, mesh_file.image_uv(np.array([[0.5 / 3, 0.875]])))
    np.testing.assert_allclose(top[0], texture[0, 0])


def test_gltf_images_are_found_by_the_rule_and_refused_when_broken(tmp_path):
    _top_red_texture(tmp_path / "textures" / "paint.png")
    (tmp_path / "model").mkdir()
    path = _quad_gltf(tmp_path / "model", "../textures/paint.png")
    assert asset_files.missing(path) == []
    part = user_mesh.load(path).parts[0]
    np.testing.assert_allclose(
        part.texture[:, 0], linear_from_srgb(np.array([RED, BLUE]) / 255.0), atol=1e-6
    )
    (tmp_path / "textures" / "paint.png").write_bytes(b"garbage")
    for method in ("ndr", "simplification"):
        with pytest.raises(AssetFileError) as err:
            LOADERS[method](path)
        assert str(err.value).startswith(
            f"{path}: {path} names paint.png ({path.parent / '..' / 'textures' / 'paint.png'}), "
            "which could not be read: it cannot be decoded"
        )


def test_a_gltf_key_set_twice_is_refused_naming_the_file_and_key(tmp_path):
    _top_red_texture(tmp_path / "paint.png")
    path = _quad_gltf(tmp_path, "paint.png")
    text = path.read_text()
    path.write_text(text.replace('"images":', '"images": [{"uri": "other.png"}], "images":', 1))
    expected = f"{path}: key 'images' is set twice in one JSON object"
    (problem,) = asset_files.missing(path)  # the DAG-time check, which each method prefixes
    assert problem.startswith(expected)
    for method, load in LOADERS.items():
        with pytest.raises(AssetFileError) as err:
            load(path)
        assert str(err.value).startswith(expected), method


def test_a_corrupt_image_embedded_in_a_glb_is_refused(tmp_path):
    box, _ = gridded_box()
    box.visual.material = trimesh.visual.material.PBRMaterial(
        baseColorTexture=Image.fromarray(np.full((4, 4, 3), 200, np.uint8))
    )
    box.export(tmp_path / "box.glb")
    data = bytearray((tmp_path / "box.glb").read_bytes())
    start = data.index(b"\x89PNG")
    data[start + 20 : start + 60] = b"\x00" * 40  # the header chunk and past it
    (tmp_path / "box.glb").write_bytes(bytes(data))
    with pytest.raises(AssetFileError, match=r"box\.glb: its image 0 \(embedded\), which could"):
        user_mesh.load(tmp_path / "box.glb")


def test_a_texture_without_texture_coordinates_is_refused(tmp_path):
    _top_red_texture(tmp_path / "paint.png")
    (tmp_path / "a.mtl").write_text("newmtl paint\nmap_Kd paint.png\n")
    (tmp_path / "a.obj").write_text(
        "mtllib a.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl paint\nf 1 2 3\n"
    )
    for method in ("ndr", "simplification"):
        with pytest.raises(
            AssetFileError,
            match=r"a\.obj: a mesh with a textured material \(paint\) has no texture coordinates",
        ):
            LOADERS[method](tmp_path / "a.obj")


def test_texture_coordinates_without_a_material_are_a_plain_surface(tmp_path):
    """trimesh makes up a 2 x 2 grey image there; the methods' own defaults apply."""
    (tmp_path / "a.obj").write_text(
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\n"
    )
    obj = user_objects.load_user_object(tmp_path / "a.obj", DEFAULTS)
    np.testing.assert_allclose(obj.albedo_diffuse, np.tile(DEFAULTS["base_colour"], (3, 1)))
    part = user_mesh.load(tmp_path / "a.obj").parts[0]
    assert part.kind == "constant"
    np.testing.assert_allclose(part.albedo, user_mesh.PLAIN_ALBEDO)


def _ascii_ply(path, vertices, faces):
    """An ASCII PLY written by hand (trimesh and PyVista refuse to write bad indices)."""
    head = ["ply", "format ascii 1.0", f"element vertex {len(vertices)}"]
    head += [f"property float {a}" for a in "xyz"]
    head += [f"element face {len(faces)}", "property list uchar int vertex_indices", "end_header"]
    body = [" ".join(map(str, v)) for v in vertices] + ["3 " + " ".join(map(str, f)) for f in faces]
    path.write_text("\n".join(head + body) + "\n")
    return path


@pytest.mark.parametrize("method", sorted(LOADERS))
@pytest.mark.parametrize(
    ("index", "counts"),
    [
        (
            5000,
            "1 face indices out of range for its 162 vertices: 0 negative, 1 at or past 162 "
            "(e.g. 5000)",
        ),
        (-1, "1 face indices out of range for its 162 vertices: 1 negative, 0 at or past 162"),
    ],
)
def test_ply_face_indices_out_of_range_are_refused_naming_counts(tmp_path, method, index, counts):
    sphere = trimesh.creation.icosphere(2)
    faces = sphere.faces.copy()
    faces[7, 1] = index
    path = _ascii_ply(tmp_path / "ball.ply", sphere.vertices, faces)
    with pytest.raises(AssetFileError) as err:
        LOADERS[method](path)
    assert str(err.value) == f"{path}: {counts}"


@pytest.mark.parametrize("method", sorted(LOADERS))
def test_glb_face_indices_past_the_vertices_are_refused(tmp_path, method):
    """As a corrupt (e.g. Draco-decoded) GLB gives them; trimesh writes them as told."""
    sphere = trimesh.creation.icosphere(2)
    faces = sphere.faces.copy()
    faces[[3, 9], 0] = 5000
    trimesh.Trimesh(sphere.vertices, faces, process=False).export(tmp_path / "ball.glb")
    with pytest.raises(AssetFileError) as err:
        LOADERS[method](tmp_path / "ball.glb")
    assert str(err.value) == (
        f"{tmp_path / 'ball.glb'}: 2 face indices out of range for its 162 vertices: "
        "0 negative, 2 at or past 162 (e.g. 5000)"
    )


@pytest.mark.parametrize("method", sorted(LOADERS))
def test_obj_relative_and_out_of_range_indices_are_refused(tmp_path, method):
    # "f 1 2 -1" means vertex 3 here, but trimesh reads it as the file's last vertex (4).
    path = tmp_path / "rel.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -1\nv 0 0 1\nf 1 2 4\n")
    with pytest.raises(AssetFileError) as err:
        LOADERS[method](path)
    assert str(err.value).startswith(
        f"{path}: 1 face vertex indices out of range for its 4 vertices: 1 negative (OBJ's"
    )
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 5000\nf 1 2 0\n")
    with pytest.raises(AssetFileError) as err:
        LOADERS[method](path)
    assert str(err.value).endswith("2 outside 1..3 (e.g. 5000)")


@pytest.mark.parametrize("method", sorted(LOADERS))
def test_a_folder_or_fifo_where_the_mesh_should_be_is_named_as_such(tmp_path, method):
    (tmp_path / "dir.obj").mkdir()
    os.mkfifo(tmp_path / "pipe.ply")
    with pytest.raises(AssetFileError) as err:
        LOADERS[method](tmp_path / "dir.obj")
    assert (
        str(err.value) == f"{tmp_path / 'dir.obj'}: is a folder, not a file; expected a mesh file"
    )
    with pytest.raises(AssetFileError) as err:
        LOADERS[method](tmp_path / "pipe.ply")
    assert str(err.value) == (
        f"{tmp_path / 'pipe.ply'}: is a named pipe (FIFO), not a file; expected a mesh file"
    )


def test_the_dag_time_check_names_folders_fifos_and_broken_links(tmp_path):
    (tmp_path / "a.mtl").mkdir()
    (tmp_path / "a.obj").write_text("mtllib a.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    os.symlink(tmp_path / "gone.png", tmp_path / "link.png")
    assert asset_files.missing(tmp_path / "a.obj") == [
        f"{tmp_path / 'a.obj'} names a.mtl ({tmp_path / 'a.mtl'}), which is a folder, not a file"
    ]
    assert user_paths.file_problem(tmp_path / "link.png") == (
        f"is a symbolic link to {tmp_path / 'gone.png'}, which does not exist"
    )
    os.mkfifo(tmp_path / "b.obj")
    assert asset_files.references(tmp_path / "b.obj") == []  # not opened: it would block
    with pytest.raises(AssetFileError, match=r"b\.obj: is a named pipe \(FIFO\)"):
        asset_files.check(tmp_path / "b.obj", asset_files.TRIMESH_SUFFIXES)


def test_a_ply_texture_file_is_an_input_and_is_read(tmp_path):
    """PLY's ``comment TextureFile`` (as Meshlab writes it), in a sibling folder."""
    box, texture = gridded_box()
    box.export(tmp_path / "box.ply")
    text = (tmp_path / "box.ply").read_bytes()
    text = text.replace(b"ply\n", b"ply\ncomment TextureFile ../maps/box.png\n", 1)
    (tmp_path / "m").mkdir()
    (tmp_path / "m" / "box.ply").write_bytes(text)
    (tmp_path / "maps").mkdir()
    Image.fromarray(texture).save(tmp_path / "maps" / "box.png")
    assert asset_files.asset_inputs(str(tmp_path / "m" / "box.ply")) == [
        str(tmp_path / "m" / ".." / "maps" / "box.png")
    ]
    assert_texture_loaded(tmp_path / "m" / "box.ply", texture)
    (tmp_path / "maps" / "box.png").write_bytes(b"broken")
    with pytest.raises(AssetFileError, match=r"box\.ply names box\.png .*could not be read"):
        user_mesh.load(tmp_path / "m" / "box.ply")


def test_vtk_face_indices_are_checked(tmp_path):
    sphere = pv.Sphere(theta_resolution=8, phi_resolution=6)
    faces = sphere.faces.reshape(-1, 4).copy()
    faces[3, 2] = 5000
    bad = pv.PolyData(sphere.points, faces.ravel())
    bad.save(str(tmp_path / "bad.vtk"))
    for method in ("prt", "ndr"):
        with pytest.raises(
            AssetFileError,
            match=rf"bad\.vtk: 1 face indices out of range for its {sphere.n_points} vertices",
        ):
            LOADERS[method](tmp_path / "bad.vtk")


# Repairs every method shares: vertices no triangle uses, the winding, Draco data.


def _signed_volume(vertices, faces) -> float:
    p = np.asarray(vertices, np.float64)[faces]
    return float(np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() / 6)


def _mesh_warnings(caplog) -> list[str]:
    return [
        r.getMessage()
        for r in caplog.records
        if r.name == "neurender.mesh_file" and r.levelname == "WARNING"
    ]


@pytest.mark.parametrize("suffix", ["ply", "glb"])
def test_a_vertex_no_triangle_uses_does_not_move_or_shrink_the_object(tmp_path, suffix, caplog):
    """A sphere and one vertex left at x = 100 where faces were deleted (PLY and GLB keep
    it): every method places the sphere by its own vertices, with a warning naming it."""
    ball = trimesh.creation.icosphere(2)
    path = tmp_path / f"ball.{suffix}"
    trimesh.Trimesh(np.vstack([ball.vertices, [[100, 0, 0]]]), ball.faces, process=False).export(
        path
    )
    caplog.set_level(logging.INFO)
    obj = user_objects.load_user_object(path, DEFAULTS)
    # NDR: the surface fills the unit sphere about the origin.
    np.testing.assert_allclose((obj.vertices.min(0) + obj.vertices.max(0)) / 2, 0, atol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(obj.vertices, axis=1).max(), 1, rtol=1e-6)
    assert len(obj.vertices) == len(ball.vertices)
    for vertices in (user_mesh.load(path).vertices, objects.read_mesh(path)[0]):
        np.testing.assert_allclose(vertices.min(0), ball.vertices.min(0), atol=1e-6)
        np.testing.assert_allclose(vertices.max(0), ball.vertices.max(0), atol=1e-6)
    (message,) = set(_mesh_warnings(caplog))
    assert message.startswith(f"{path}: 1 of its 163 vertices belong to no triangle")
    assert "[100.0, 0.0, 0.0]" in message and "left out" in message


def test_dropping_unused_vertices_keeps_texture_coordinates_with_their_vertices(tmp_path):
    box, texture = gridded_box()
    material = trimesh.visual.material.PBRMaterial(
        baseColorTexture=Image.fromarray(texture), metallicFactor=0.0
    )
    uv = np.vstack([box.visual.uv, [[0.9, 0.1]]])
    trimesh.Trimesh(
        np.vstack([box.vertices, [[50.0, 3.0, -7.0]]]),
        box.faces,
        visual=trimesh.visual.TextureVisuals(uv=uv, material=material),
        process=False,
    ).export(tmp_path / "box.glb")
    part = mesh_file.read(tmp_path / "box.glb").parts[0]
    np.testing.assert_allclose(part.vertices, box.vertices, atol=1e-6)
    np.testing.assert_allclose(part.visual.uv, box.visual.uv, atol=1e-6)
    mesh = user_mesh.load(tmp_path / "box.glb")
    faces = np.arange(len(mesh.parts[0].faces))
    for k in range(3):
        seen = mesh.albedo_at(faces, np.tile(np.eye(3)[k], (len(faces), 1)))
        want = expected_colours(mesh.parts[0].vertices, texture)[mesh.parts[0].faces[:, k]]
        np.testing.assert_allclose(seen, want, atol=1e-6)


def test_primitives_sharing_one_vertex_list_are_read_without_a_warning(tmp_path, caplog):
    """A glTF's primitives may index one POSITION accessor: each part then has vertices
    only the other uses, inside the surface's box; logged at info level only."""
    box = trimesh.creation.box()
    box.export(tmp_path / "box.glb")
    data = (tmp_path / "box.glb").read_bytes()
    (length,) = struct.unpack_from("<I", data, 12)
    tree, rest = json.loads(data[20 : 20 + length]), data[20 + length :]
    indices = tree["meshes"][0]["primitives"][0]["indices"]
    tree["accessors"][indices]["count"] = 18
    tree["accessors"].append(dict(tree["accessors"][indices], byteOffset=72))
    primitive = dict(tree["meshes"][0]["primitives"][0], indices=len(tree["accessors"]) - 1)
    tree["meshes"][0]["primitives"].append(primitive)
    text = json.dumps(tree).encode()
    text += b" " * (-len(text) % 4)
    head = struct.pack("<4sII", b"glTF", 2, 20 + len(text) + len(rest))
    (tmp_path / "shared.glb").write_bytes(
        head + struct.pack("<I4s", len(text), b"JSON") + text + rest
    )
    with caplog.at_level(logging.INFO, logger="neurender.mesh_file"):
        mesh = mesh_file.read(tmp_path / "shared.glb")
    assert [len(p.faces) for p in mesh.parts] == [6, 6]
    assert all(len(p.vertices) == len(np.unique(p.faces)) for p in mesh.parts)
    assert not _mesh_warnings(caplog)
    assert "belong to no triangle; left out" in caplog.text
    vertices, faces = mesh.merged()
    assert _signed_volume(vertices, faces) == pytest.approx(1.0)


def test_sequence_frames_drop_the_same_unused_vertices(tmp_path):
    """DeepPRT compares frames by vertex index: frames with one triangle list drop the same
    vertices, wherever the unused one moved."""
    from neurender.prt import animations

    ball = trimesh.creation.icosphere(2)
    files = []
    for k, stray in enumerate(([100, 0, 0], [0, -40, 5])):
        vertices = np.insert(ball.vertices * (1 + 0.1 * k), 7, stray, axis=0)
        faces = np.where(ball.faces >= 7, ball.faces + 1, ball.faces)
        files.append(tmp_path / f"frame{k}.ply")
        trimesh.Trimesh(vertices, faces, process=False).export(files[-1])
    frames = animations.load_frames(files, "prt.user_sequences.ball.frames")
    np.testing.assert_array_equal(frames.faces, ball.faces)
    np.testing.assert_allclose(frames.positions[1], 1.1 * ball.vertices, atol=1e-5)


def _inside_out_ball(path, normals: str):
    """An icosphere with every triangle wound clockwise seen from outside, vertex colours
    that follow the position, and file normals ``inward`` (as its winding says) or
    ``outward`` (a mirrored export that transformed its normals right)."""
    ball = trimesh.creation.icosphere(2)
    colours = np.column_stack([(ball.vertices + 1) * 127, np.full(len(ball.vertices), 255)])
    sign = -1.0 if normals == "inward" else 1.0
    trimesh.Trimesh(
        ball.vertices,
        ball.faces[:, ::-1],
        vertex_colors=colours.astype(np.uint8),
        vertex_normals=sign * ball.vertices,
        process=False,
    ).export(path)
    return ball


@pytest.mark.parametrize("normals", ["inward", "outward"])
def test_a_closed_surface_wound_inside_out_is_turned_outward_in_every_method(
    tmp_path, normals, caplog
):
    path = tmp_path / "ball.ply"
    ball = _inside_out_ball(path, normals)
    caplog.set_level(logging.WARNING)
    part = mesh_file.read(path).parts[0]
    assert _signed_volume(part.vertices, part.faces) > 4
    # Normals face outward whatever the file's say; the colours stay with their vertices.
    np.testing.assert_allclose(part.vertices, ball.vertices, atol=1e-6)
    assert (np.einsum("ij,ij->i", part.vertex_normals, part.vertices) > 0.9).all()
    expected = ((ball.vertices + 1) * 127).astype(np.uint8)
    np.testing.assert_array_equal(part.visual.vertex_colors[:, :3], expected)
    obj = user_objects.load_user_object(path, DEFAULTS)
    assert _signed_volume(obj.vertices, obj.faces) > 0
    assert (np.einsum("ij,ij->i", obj.normals, obj.vertices) > 0.9).all()
    mesh = user_mesh.load(path)
    assert _signed_volume(mesh.vertices, mesh.faces) > 4
    welded_normals = mesh.normals()[0]
    assert (np.einsum("ij,ij->i", welded_normals, mesh.parts[0].vertices) > 0.9).all()
    message = _mesh_warnings(caplog)[0]
    assert message.startswith(
        f"{path}: 320 of the 320 triangles of its closed surfaces are wound inside out"
    )
    assert "flipped so that the normals point outward" in message


def test_a_surface_split_into_parts_is_turned_outward_as_one(tmp_path, caplog):
    """Two glTF primitives, each half of an inside-out sphere (open alone, closed
    together): both halves are flipped."""
    ball = trimesh.creation.icosphere(2)
    top = ball.triangles_center[:, 2] > 0
    scene = trimesh.Scene()
    for k, half in enumerate((top, ~top)):
        piece = trimesh.Trimesh(ball.vertices, ball.faces[half][:, ::-1], process=False)
        piece.remove_unreferenced_vertices()
        scene.add_geometry(piece, geom_name=f"half{k}")
    scene.export(tmp_path / "halves.glb")
    caplog.set_level(logging.WARNING)
    vertices, faces = mesh_file.read(tmp_path / "halves.glb").merged()
    assert _signed_volume(vertices, faces) > 4
    obj = user_objects.load_user_object(tmp_path / "halves.glb", DEFAULTS)
    assert _signed_volume(obj.vertices, obj.faces) > 0
    mesh = user_mesh.load(tmp_path / "halves.glb")
    assert _signed_volume(mesh.vertices, mesh.faces) > 4
    assert "320 of the 320 triangles of its closed surfaces" in _mesh_warnings(caplog)[0]


def test_an_open_surface_keeps_the_winding_most_of_its_triangles_have(tmp_path, caplog):
    ball = trimesh.creation.icosphere(2)
    ball.update_faces(ball.triangles_center[:, 2] > 0.3)
    ball.remove_unreferenced_vertices()
    cap = ball.faces
    faces = cap.copy()
    faces[:5] = faces[:5, ::-1]
    caplog.set_level(logging.WARNING)
    trimesh.Trimesh(ball.vertices, faces, process=False).export(tmp_path / "cap.ply")
    part = mesh_file.read(tmp_path / "cap.ply").parts[0]
    normals = trimesh.triangles.normals(part.vertices[part.faces])[0]
    assert (np.einsum("ij,ij->i", normals, part.vertices[part.faces].mean(1)) > 0).all()
    (message,) = _mesh_warnings(caplog)
    assert message.startswith(
        f"{tmp_path / 'cap.ply'}: 5 of the {len(cap)} triangles of its open surfaces are wound "
        "against most of their surface's triangles"
    )
    # Wound all one way, an open surface has no wrong side: as stored, without a word.
    caplog.clear()
    trimesh.Trimesh(ball.vertices, cap[:, ::-1], process=False).export(tmp_path / "back.ply")
    part = mesh_file.read(tmp_path / "back.ply").parts[0]
    np.testing.assert_array_equal(part.faces, cap[:, ::-1])
    assert not _mesh_warnings(caplog)


def test_a_hollow_ball_keeps_its_cavity_facing_inward(tmp_path, caplog):
    """A closed shell inside another, wound inward on purpose (the cavity's normals face
    into it), is no inside-out surface."""
    ball = trimesh.creation.icosphere(2)
    vertices = np.vstack([ball.vertices, 0.5 * ball.vertices])
    faces = np.vstack([ball.faces, ball.faces[:, ::-1] + len(ball.vertices)])
    trimesh.Trimesh(vertices, faces, process=False).export(tmp_path / "hollow.ply")
    caplog.set_level(logging.WARNING)
    part = mesh_file.read(tmp_path / "hollow.ply").parts[0]
    np.testing.assert_array_equal(part.faces, faces)
    assert not _mesh_warnings(caplog)


def test_deepprt_reads_the_winding_as_stored(tmp_path):
    """DeepPRT orients the rest frame itself, once for every frame (prt.disk)."""
    path = tmp_path / "ball.ply"
    ball = _inside_out_ball(path, "inward")
    np.testing.assert_array_equal(objects.read_mesh(path)[1], ball.faces[:, ::-1])


def _draco_glb(path, blob: bytes, count: int, triangles: int):
    """A GLB with one Draco-compressed primitive (``blob``), as Blender's exporter with
    "Compression" writes it: accessors without a bufferView."""
    tree = {
        "asset": {"version": "2.0", "generator": "Khronos glTF Blender I/O"},
        "extensionsUsed": ["KHR_draco_mesh_compression"],
        "extensionsRequired": ["KHR_draco_mesh_compression"],
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [
            {
                "name": "Rock",
                "primitives": [
                    {
                        "attributes": {"POSITION": 0},
                        "indices": 1,
                        "extensions": {
                            "KHR_draco_mesh_compression": {
                                "bufferView": 0,
                                "attributes": {"POSITION": 0},
                            }
                        },
                    }
                ],
            }
        ],
        "accessors": [
            {"componentType": 5126, "count": count, "type": "VEC3"},
            {"componentType": 5125, "count": 3 * triangles, "type": "SCALAR"},
        ],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": len(blob)}],
        "buffers": [{"byteLength": len(blob)}],
    }
    tree["accessors"][0] |= {"min": [-1, -1, -1], "max": [1, 1, 1]}
    text = json.dumps(tree).encode()
    text += b" " * (-len(text) % 4)
    data = blob + bytes(-len(blob) % 4)
    head = struct.pack("<4sII", b"glTF", 2, 12 + 8 + len(text) + 8 + len(data))
    path.write_bytes(
        head
        + struct.pack("<I4s", len(text), b"JSON")
        + text
        + struct.pack("<I4s", len(data), b"BIN\0")
        + data
    )
    return path


@pytest.mark.parametrize("method", sorted(LOADERS))
def test_draco_data_that_cannot_be_decoded_is_named_before_the_bounding_box(
    tmp_path, monkeypatch, method
):
    import DracoPy

    ball = trimesh.creation.icosphere(2)
    blob = DracoPy.encode(ball.vertices.astype(np.float32), ball.faces.astype(np.uint32))
    good = _draco_glb(tmp_path / "good.glb", blob, len(ball.vertices), len(ball.faces))
    vertices, faces = mesh_file.read(good).merged()
    assert len(faces) == len(ball.faces)
    assert _signed_volume(vertices, faces) == pytest.approx(
        _signed_volume(ball.vertices, ball.faces), rel=1e-3
    )
    LOADERS[method](good)
    # A truncated download.
    cut = _draco_glb(tmp_path / "cut.glb", blob[: len(blob) // 2], len(ball.vertices), 320)
    with pytest.raises(AssetFileError) as err:
        LOADERS[method](cut)
    message = str(err.value)
    assert message.startswith(f"{cut}: mesh 0 (Rock) primitive 0: its Draco-compressed data")
    assert f"{len(blob) // 2} bytes) cannot be decoded by DracoPy (FileTypeException:" in message
    assert "bounding box" not in message
    # An environment without DracoPy.
    monkeypatch.setitem(sys.modules, "DracoPy", None)
    with pytest.raises(AssetFileError) as err:
        LOADERS[method](good)
    assert str(err.value).startswith(
        f"{good}: its meshes are Draco-compressed (glTF extension KHR_draco_mesh_compression), "
        "which needs the Python package DracoPy: pip install DracoPy"
    )
