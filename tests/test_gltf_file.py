"""A user's glTF through every method's loader: KHR_texture_transform and texCoord applied
once, as the specification says; required extensions the reader does not honour refused by
name; used ones reported. The files are written by hand (JSON + buffer), as a tool would."""

import base64
import json
import logging
import math
import struct

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from PIL import Image

from neurender import gltf_file, mesh_file
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
POSITIONS = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float32)
#: glTF texture coordinates (v down) of the quad's corners: two sets.
UV0 = np.array([[0.25, 0.75], [0.75, 0.75], [0.75, 0.25], [0.25, 0.25]], np.float32)
UV1 = np.array([[0.1, 0.2], [0.3, 0.4], [0.5, 0.6], [0.7, 0.9]], np.float32)
#: 4 x 4 texture of four 2 x 2 quadrants: top-left, top-right, bottom-left, bottom-right.
QUADRANTS = np.array([[200, 30, 30], [30, 200, 30], [30, 30, 200], [220, 220, 40]], np.uint8)
TRANSFORM = {"offset": [0.3, -0.2], "rotation": 0.7, "scale": [2.0, 0.5]}


def _texture(path):
    rows = [QUADRANTS[[0, 0, 1, 1]]] * 2 + [QUADRANTS[[2, 2, 3, 3]]] * 2
    Image.fromarray(np.stack(rows)).save(path)


def _quad(folder, material: dict, fmt="gltf", used=(), required=(), uvs=(UV0, UV1)) -> str:
    """A textured quad written by hand as ``quad.gltf`` (buffer as a ``data:`` URI) or
    ``quad.glb`` (buffer in the binary chunk), with texture ``paint.png``, ``material`` and
    the extension lists; ``uvs``: its TEXCOORD_0, TEXCOORD_1, ... (float32 arrays)."""
    _texture(folder / "paint.png")
    indices = np.array([0, 1, 2, 0, 2, 3], np.uint16)
    arrays = [POSITIONS, indices, *uvs]
    blob, views = b"", []
    for array in arrays:
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": array.nbytes})
        blob += array.tobytes() + b"\0" * (-array.nbytes % 4)
    accessors = [
        {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3"},
        {"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"},
    ]
    accessors[0] |= {"min": [-1, -1, 0], "max": [1, 1, 0]}
    for k, uv in enumerate(uvs):
        kind = {np.dtype(np.float32): 5126, np.dtype(np.uint8): 5121}[uv.dtype]
        accessors.append({"bufferView": 2 + k, "componentType": kind, "count": 4, "type": "VEC2"})
        if kind != 5126:
            accessors[-1]["normalized"] = True
    attributes = {"POSITION": 0} | {f"TEXCOORD_{k}": 2 + k for k in range(len(uvs))}
    tree = {
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": attributes, "indices": 1, "material": 0}]}],
        "materials": [material],
        "textures": [{"source": 0}],
        "images": [{"uri": "paint.png"}],
        "buffers": [{"byteLength": len(blob)}],
        "bufferViews": views,
        "accessors": accessors,
    }
    tree |= {"extensionsUsed": list(used)} if used else {}
    tree |= {"extensionsRequired": list(required)} if required else {}
    return _write(folder, tree, blob, fmt)


def _write(folder, tree: dict, blob: bytes, fmt: str):
    path = folder / f"quad.{fmt}"
    if fmt == "gltf":
        uri = "data:application/octet-stream;base64," + base64.b64encode(blob).decode()
        tree["buffers"][0]["uri"] = uri
        path.write_text(json.dumps(tree))
        return path
    text = json.dumps(tree).encode()
    text += b" " * (-len(text) % 4)
    blob += b"\0" * (-len(blob) % 4)
    chunks = struct.pack("<I4s", len(text), b"JSON") + text
    chunks += struct.pack("<I4s", len(blob), b"BIN\0") + blob
    path.write_bytes(struct.pack("<4sII", b"glTF", 2, 12 + len(chunks)) + chunks)
    return path


def _base(info: dict) -> dict:
    return {"pbrMetallicRoughness": {"baseColorTexture": {"index": 0} | info}}


def _transformed(uv, offset=(0, 0), rotation=0.0, scale=(1, 1)):
    """The specification's ``T(offset) R(rotation) S(scale) uv``, written out."""
    x, y = uv[:, 0] * scale[0], uv[:, 1] * scale[1]
    c, s = math.cos(rotation), math.sin(rotation)
    return np.column_stack([c * x + s * y + offset[0], -s * x + c * y + offset[1]])


def _uv(path) -> np.ndarray:
    """The part's texture coordinates as glTF writes them (v down)."""
    return mesh_file.image_uv(mesh_file.read(path).parts[0].visual.uv)


@pytest.mark.parametrize("fmt", ["gltf", "glb"])
@pytest.mark.parametrize(
    ("info", "expected"),
    [
        ({"extensions": {"KHR_texture_transform": TRANSFORM}}, _transformed(UV0, **TRANSFORM)),
        (
            {"texCoord": 0, "extensions": {"KHR_texture_transform": TRANSFORM | {"texCoord": 1}}},
            _transformed(UV1, **TRANSFORM),
        ),
        ({"texCoord": 1}, UV1),
    ],
    ids=["transform", "transform-on-texcoord-1", "texcoord-1"],
)
def test_the_coordinates_a_texture_samples_are_transformed_once(tmp_path, fmt, info, expected):
    """offset, rotation, non-uniform scale and the texCoord override, as required in the
    file: the loaded coordinates are the specification's, applied once (twice, or not at
    all, or with the other rotation sign or order, would differ)."""
    required = ["KHR_texture_transform"] if "extensions" in info else []
    path = _quad(tmp_path, _base(info), fmt, used=required, required=required)
    np.testing.assert_allclose(_uv(path), expected, atol=1e-6)
    # The copy trimesh reads holds the transform no more: no trimesh applies it again.
    assert b'KHR_texture_transform": {' not in gltf_file.prepare(path, True)


def test_the_specification_example_samples_the_lower_left_quadrant(tmp_path):
    """offset [0, 1], rotation pi/2, scale [0.5, 0.5] maps the unit square onto the image's
    lower-left quadrant (the specification's example; the other rotation sign would give
    the top-right one); both methods that read colour see it."""
    example = {"offset": [0, 1], "rotation": math.pi / 2, "scale": [0.5, 0.5]}
    info = {"extensions": {"KHR_texture_transform": example}}
    path = _quad(tmp_path, _base(info), required=["KHR_texture_transform"])
    lower_left = linear_from_srgb(QUADRANTS[2] / 255.0)
    obj = user_objects.load_user_object(path, DEFAULTS)
    np.testing.assert_allclose(obj.albedo_diffuse, np.tile(lower_left, (4, 1)), atol=1e-6)
    mesh = user_mesh.load(path)
    corners = mesh.parts[0].albedo_at(np.array([0, 0, 0]), np.eye(3))
    np.testing.assert_allclose(corners, np.tile(lower_left, (3, 1)), atol=1e-6)


def test_a_file_without_the_extension_loads_unchanged(tmp_path):
    path = _quad(tmp_path, _base({}), "glb")
    assert gltf_file.prepare(path, True) is None  # trimesh reads the file itself
    np.testing.assert_allclose(_uv(path), UV0, atol=1e-7)
    top_right = linear_from_srgb(QUADRANTS[1] / 255.0)  # UV0's vertex 2 is at (0.75, 0.25)
    np.testing.assert_allclose(
        user_mesh.load(path).parts[0].albedo_at([0], [[0, 0, 1]])[0], top_right, atol=1e-6
    )


def test_normalized_integer_coordinates_are_decoded(tmp_path):
    """glTF allows unsigned-byte texture coordinates, normalized: c / 255."""
    stored = np.round(UV0 * 255).astype(np.uint8)
    path = _quad(tmp_path, _base({}), uvs=(stored,))
    np.testing.assert_allclose(_uv(path), stored / 255.0, atol=1e-6)


def test_draco_compressed_coordinates_are_transformed(tmp_path):
    import DracoPy

    _texture(tmp_path / "paint.png")
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    blob = DracoPy.encode(POSITIONS, faces, tex_coord=UV0.astype(np.float64), preserve_order=True)
    decoded = DracoPy.decode(blob)
    ids = {a["attribute_type"]: a["unique_id"] for a in decoded.attributes}
    uv = next(
        a["data"]
        for a in decoded.attributes
        if a["unique_id"] == ids[DracoPy.AttributeType.TEX_COORD]
    )
    blob += b"\0" * (-len(blob) % 4)
    draco = {
        "bufferView": 0,
        "attributes": {
            "POSITION": ids[DracoPy.AttributeType.POSITION],
            "TEXCOORD_0": ids[DracoPy.AttributeType.TEX_COORD],
        },
    }
    primitive = {
        "attributes": {"POSITION": 0, "TEXCOORD_0": 1},
        "indices": 2,
        "material": 0,
        "extensions": {"KHR_draco_mesh_compression": draco},
    }
    extensions = ["KHR_draco_mesh_compression", "KHR_texture_transform"]
    tree = {
        "asset": {"version": "2.0"},
        "extensionsUsed": extensions,
        "extensionsRequired": extensions,
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [primitive]}],
        "materials": [_base({"extensions": {"KHR_texture_transform": TRANSFORM}})],
        "textures": [{"source": 0}],
        "images": [{"uri": "paint.png"}],
        "buffers": [{"byteLength": len(blob)}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": len(blob)}],
        "accessors": [
            {
                "componentType": 5126,
                "count": 4,
                "type": "VEC3",
                "min": [-1, -1, 0],
                "max": [1, 1, 0],
            },
            {"componentType": 5126, "count": 4, "type": "VEC2"},
            {"componentType": 5123, "count": 6, "type": "SCALAR"},
        ],
    }
    path = _write(tmp_path, tree, blob, "glb")
    np.testing.assert_allclose(_uv(path), _transformed(np.asarray(uv), **TRANSFORM), atol=1e-6)


def test_textures_of_one_material_at_different_coordinates_are_refused(tmp_path):
    material = _base({"extensions": {"KHR_texture_transform": {"scale": [2, 2]}}})
    material["name"] = "paint"
    material["pbrMetallicRoughness"]["metallicRoughnessTexture"] = {"index": 0}
    path = _quad(tmp_path, material, required=["KHR_texture_transform"])
    for method in ("ndr", "simplification"):
        with pytest.raises(AssetFileError) as err:
            LOADERS[method](path)
        message = str(err.value)
        assert message.startswith(f'{path}: material 0 "paint" samples its textures at different')
        assert "baseColorTexture samples TEXCOORD_0 through KHR_texture_transform" in message
        assert "metallicRoughnessTexture samples TEXCOORD_0 untransformed" in message
    objects.read_mesh(path)  # DeepPRT reads the geometry only


def test_a_normal_map_at_other_coordinates_is_dropped_with_a_warning(tmp_path, caplog):
    material = _base({"extensions": {"KHR_texture_transform": {"scale": [2, 2]}}})
    material["normalTexture"] = {"index": 0}
    path = _quad(tmp_path, material, required=["KHR_texture_transform"])
    with caplog.at_level(logging.WARNING, logger="neurender.gltf_file"):
        part = mesh_file.read(path).parts[0]
    assert part.visual.material.normalTexture is None
    assert part.visual.material.baseColorTexture is not None
    assert f"{path}: material 0: its normalTexture samples TEXCOORD_0 untransformed" in caplog.text
    np.testing.assert_allclose(_uv(path), UV0 * 2, atol=1e-6)


@pytest.mark.parametrize(
    ("key", "info"),
    [
        ("extensions.KHR_texture_transform.scale = [2]", {"scale": [2]}),
        ("extensions.KHR_texture_transform.rotation = 'a'", {"rotation": "a"}),
        ("extensions.KHR_texture_transform.texCoord = -1", {"texCoord": -1}),
    ],
)
def test_an_invalid_transform_is_refused_naming_the_key(tmp_path, key, info):
    path = _quad(tmp_path, _base({"extensions": {"KHR_texture_transform": info}}))
    with pytest.raises(AssetFileError) as err:
        user_mesh.load(path)
    assert str(err.value).startswith(f"{path}: material 0 baseColorTexture.{key}; expected")


def test_a_texture_coordinate_set_the_primitive_lacks_is_refused(tmp_path):
    path = _quad(tmp_path, _base({"texCoord": 2}))
    with pytest.raises(AssetFileError) as err:
        user_objects.load_user_object(path, DEFAULTS)
    assert str(err.value) == (
        f"{path}: mesh 0 primitive 0 (material 0): its textures sample TEXCOORD_2, which the "
        "primitive does not have (its attributes: POSITION, TEXCOORD_0, TEXCOORD_1)"
    )


@pytest.mark.parametrize("fmt", ["gltf", "glb"])
def test_a_required_extension_the_reader_does_not_support_is_refused(tmp_path, fmt):
    path = _quad(
        tmp_path,
        _base({}),
        fmt,
        used=["EXT_meshopt_compression"],
        required=["EXT_meshopt_compression"],
    )
    for method in LOADERS:
        with pytest.raises(AssetFileError) as err:
            LOADERS[method](path)
        assert str(err.value).startswith(
            f"{path}: requires glTF extension(s) EXT_meshopt_compression (extensionsRequired), "
            "which this reader does not support"
        )


def test_a_required_material_extension_is_refused_where_materials_are_read(tmp_path):
    name = "KHR_materials_clearcoat"
    path = _quad(tmp_path, _base({}), used=[name], required=[name])
    for method in ("ndr", "simplification"):
        with pytest.raises(AssetFileError, match=f"requires glTF extension\\(s\\) {name} "):
            LOADERS[method](path)
    objects.read_mesh(path)  # DeepPRT reads the geometry only


def test_a_used_extension_the_reader_ignores_is_reported(tmp_path, caplog):
    path = _quad(tmp_path, _base({}), used=["KHR_materials_sheen", "KHR_xmp_json_ld"])
    with caplog.at_level(logging.WARNING, logger="neurender.gltf_file"):
        user_mesh.load(path)
    assert f"{path}: uses glTF extension(s) KHR_materials_sheen (extensionsUsed)" in caplog.text
    assert "KHR_xmp_json_ld" not in caplog.text  # metadata changes nothing shown


_JSON = st.recursive(
    st.none() | st.booleans() | st.integers(-2, 3) | st.floats() | st.text("ab_0", max_size=3),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text("ab", max_size=2), inner),
    max_leaves=4,
)


def _paths(node, prefix=()):
    """Every key path into a JSON tree."""
    items = (
        node.items()
        if isinstance(node, dict)
        else enumerate(node)
        if isinstance(node, list)
        else ()
    )
    for key, value in items:
        yield (*prefix, key)
        yield from _paths(value, (*prefix, key))


@settings(
    max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(data=st.data())
def test_fuzz_edited_json_gives_a_clean_error_or_a_valid_mesh(tmp_path, data):
    """Any value anywhere in a file that uses every feature here: an AssetFileError naming
    the file, or a valid mesh."""
    transform = TRANSFORM | {"texCoord": 1}
    material = _base({"extensions": {"KHR_texture_transform": transform}})
    material["pbrMetallicRoughness"]["metallicRoughnessTexture"] = {"index": 0, "texCoord": 1}
    material["normalTexture"] = {"index": 0}
    required = ["KHR_texture_transform"]
    tree = json.loads(_quad(tmp_path, material, used=required, required=required).read_text())
    for _ in range(data.draw(st.integers(1, 3))):
        *parents, key = data.draw(st.sampled_from(sorted(_paths(tree), key=str)))
        node = tree
        for parent in parents:
            node = node[parent]
        node[key] = data.draw(_JSON)
    path = tmp_path / "edited.gltf"
    path.write_text(json.dumps(tree))
    for materials in (True, False):
        try:
            mesh = mesh_file.read(path, materials=materials)
        except AssetFileError as err:
            assert str(path) in str(err)
            continue
        for part in mesh.parts:
            uv = getattr(part.visual, "uv", None)
            assert uv is None or np.asarray(uv).shape == (len(part.vertices), 2)


@pytest.mark.parametrize("count", [False, 2])
def test_texture_coordinates_not_one_per_vertex_are_an_error_naming_the_file(tmp_path, count):
    """A TEXCOORD accessor whose count is no integer, or not the vertices', fails cleanly
    (hypothesis found ``"count": false``, which Python reads as 0)."""
    material = _base({"extensions": {"KHR_texture_transform": TRANSFORM | {"texCoord": 1}}})
    required = ["KHR_texture_transform"]
    tree = json.loads(_quad(tmp_path, material, used=required, required=required).read_text())
    index = tree["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_1"]
    tree["accessors"][index]["count"] = count
    path = tmp_path / "edited.gltf"
    path.write_text(json.dumps(tree))
    expected = "expected an integer of at least 1" if count is False else "one per vertex"
    with pytest.raises(AssetFileError, match=expected) as err:
        mesh_file.read(path, materials=True)
    assert str(path) in str(err.value)


@pytest.mark.parametrize("value", [False, True, 0])
def test_an_attribute_that_is_no_accessor_index_or_of_the_wrong_type_is_refused(tmp_path, value):
    """``TEXCOORD_0: false`` (hypothesis found it: Python reads it as accessor 0) or the
    POSITION accessor's index as TEXCOORD_0 would give trimesh positions as texture
    coordinates; ``true`` reads as accessor 1, the indices'. Refused, naming the file and
    the key, whether materials are read or not."""
    tree = json.loads(_quad(tmp_path, _base({})).read_text())
    tree["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"] = value
    path = tmp_path / "edited.gltf"
    path.write_text(json.dumps(tree))
    key = "meshes[0].primitives[0].attributes.TEXCOORD_0"
    expected = (
        f"{key} = 0, an accessor of type 'VEC3'; expected VEC2 for TEXCOORD_0"
        if not isinstance(value, bool)
        else f"{key} = {json.dumps(value)}; expected an accessor's index"
    )
    for materials in (True, False):
        with pytest.raises(AssetFileError) as err:
            mesh_file.read(path, materials=materials)
        assert str(err.value) == f"{path}: {expected}"
