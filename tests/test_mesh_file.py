"""The one reader of a user's mesh file, through every method's loader, on files made by
other tools (trimesh, PyVista, Pillow, a glTF written by hand) and laid out as users lay
them out: textures found by one rule or refused by name, indices checked, one v convention."""

import base64
import json
import os
import shutil

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
