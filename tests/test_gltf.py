"""GLB files of :mod:`neurender.gltf`: read back by trimesh (an independent reader) with
the same vertices, faces, colours and textures; 16-bit indices below 65536 vertices."""

import io as _io
import json
import struct

import numpy as np
import pytest
import trimesh
from PIL import Image

from neurender import gltf


def _tree(data: bytes) -> dict:
    length, kind = struct.unpack_from("<I4s", data, 12)
    assert data[:4] == b"glTF" and kind == b"JSON"
    assert struct.unpack_from("<I", data, 8)[0] == len(data)
    return json.loads(data[20 : 20 + length])


def _accessor(data: bytes, tree: dict, index: int) -> np.ndarray:
    """An accessor's values read straight from the GLB's binary chunk."""
    a = tree["accessors"][index]
    view = tree["bufferViews"][a["bufferView"]]
    start = 20 + struct.unpack_from("<I", data, 12)[0] + 8 + view["byteOffset"]
    dtype = {5126: "<f4", 5125: "<u4", 5123: "<u2"}[a["componentType"]]
    width = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}[a["type"]]
    return np.frombuffer(data, dtype, a["count"] * width, start).reshape(a["count"], width)


def _quad(**extra) -> gltf.Primitive:
    positions = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float64)
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    return gltf.Primitive(positions, faces, **{"normals": np.tile([0.0, 0.0, 1.0], (4, 1))} | extra)


def test_a_coloured_mesh_reads_back_with_its_vertices_faces_and_colours():
    colours = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]], np.float64)
    data = gltf.glb([_quad(colours=colours)], "quad")
    mesh = trimesh.load(_io.BytesIO(data), file_type="glb", force="mesh", process=False)
    np.testing.assert_allclose(mesh.vertices, _quad().positions)
    np.testing.assert_array_equal(mesh.faces, _quad().faces)
    tree = _tree(data)
    primitive = tree["meshes"][0]["primitives"][0]
    np.testing.assert_array_equal(
        _accessor(data, tree, primitive["attributes"]["COLOR_0"]), colours
    )
    assert tree["accessors"][tree["meshes"][0]["primitives"][0]["indices"]]["componentType"] == (
        gltf.UNSIGNED_SHORT
    )
    material = tree["materials"][0]
    assert material["extensions"]["KHR_materials_specular"]["specularFactor"] == 0.0
    assert material["pbrMetallicRoughness"]["metallicFactor"] == 0.0


def test_a_textured_part_and_a_plain_part_make_two_materials():
    texture = np.random.default_rng(0).random((8, 8, 3))
    uvs = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float64)
    textured = _quad(uvs=uvs, base_colour_png=gltf.png_bytes(texture), wrap=gltf.REPEAT)
    plain = _quad(base_colour=(0.8, 0.8, 0.8))
    plain.positions = plain.positions + [2.0, 0.0, 0.0]
    tree = _tree(gltf.glb([textured, plain], "two"))
    assert len(tree["meshes"][0]["primitives"]) == 2 and len(tree["materials"]) == 2
    assert tree["materials"][1]["pbrMetallicRoughness"]["baseColorFactor"] == [0.8, 0.8, 0.8, 1]
    assert tree["samplers"][0]["wrapS"] == gltf.REPEAT and len(tree["images"]) == 1
    scene = trimesh.load(_io.BytesIO(gltf.glb([textured, plain], "two")), file_type="glb")
    stored = [g for g in scene.geometry.values() if g.visual.kind == "texture"][0]
    image = np.asarray(stored.visual.material.baseColorTexture.convert("RGB"))
    np.testing.assert_array_equal(image, np.round(texture * 255).astype(np.uint8))


def _rock(offset) -> gltf.Primitive:
    """A 2 m icosphere centred at ``offset``, with its normals."""
    sphere = trimesh.creation.icosphere(2)
    normals = np.asarray(sphere.vertex_normals)
    return gltf.Primitive(np.asarray(sphere.vertices) + offset, np.asarray(sphere.faces), normals)


def test_a_mesh_far_from_the_origin_reads_back_to_float32_precision_of_its_own_size():
    """A 2 m rock in georeferenced coordinates (UTM, metres): the node's translation
    (float64 in the JSON) carries the offset and POSITION small float32 offsets from it, so
    trimesh, applying the node's transform, places every vertex to float32's precision of
    the rock's size (absolute float32 coordinates at y ~ 5.4e6 m are 0.5 m apart)."""
    rock = _rock([512345.678, 5412345.678, 230.5])
    data = gltf.glb([rock], "rock")
    mesh = trimesh.load(_io.BytesIO(data), file_type="glb", force="mesh", process=False)
    size = np.ptp(rock.positions, axis=0).max()
    assert np.abs(mesh.vertices - rock.positions).max() < 2.0**-23 * size
    tree = _tree(data)
    translation = np.array(tree["nodes"][0]["translation"])
    assert np.abs(translation - rock.positions.mean(0)).max() <= size
    accessor = tree["accessors"][tree["meshes"][0]["primitives"][0]["attributes"]["POSITION"]]
    stored = _accessor(data, tree, tree["meshes"][0]["primitives"][0]["attributes"]["POSITION"])
    assert np.abs(stored).max() <= size
    np.testing.assert_array_equal(accessor["min"], stored.min(0))
    np.testing.assert_array_equal(accessor["max"], stored.max(0))


def test_a_mesh_about_the_origin_gets_no_translation_and_its_own_positions():
    rock = _rock([0.01, -0.02, 0.0])
    data = gltf.glb([rock], "rock")
    tree = _tree(data)
    assert "translation" not in tree["nodes"][0]
    stored = _accessor(data, tree, tree["meshes"][0]["primitives"][0]["attributes"]["POSITION"])
    np.testing.assert_array_equal(stored, rock.positions.astype(np.float32))


def test_large_meshes_use_32_bit_indices():
    n = 70000
    positions = np.random.default_rng(1).random((n, 3))
    faces = np.arange(n - n % 3).reshape(-1, 3)
    tree = _tree(gltf.glb([gltf.Primitive(positions, faces)], "big"))
    assert tree["accessors"][1]["componentType"] == gltf.UNSIGNED_INT


def test_inconsistent_primitives_are_refused():
    with pytest.raises(ValueError, match="3 normals for 4 positions"):
        gltf.glb([_quad(normals=np.zeros((3, 3)))], "bad")
    with pytest.raises(ValueError, match="texture coordinates"):
        gltf.glb([_quad(base_colour_png=gltf.png_bytes(np.zeros((2, 2, 3))))], "bad")


def test_png_bytes_quantise_values_in_zero_one():
    values = np.array([[[0.0, 0.5, 1.0]]])
    image = np.asarray(Image.open(_io.BytesIO(gltf.png_bytes(values))))
    np.testing.assert_array_equal(image, [[[0, 128, 255]]])
