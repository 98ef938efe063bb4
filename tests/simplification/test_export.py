"""The GLB and OBJ export: glTF's tangent convention, sRGB base colour, files that read back
(trimesh) and re-render (Mitsuba) as the optimised asset does, and the Khronos validator."""

import json
import os
import shutil
import struct
import subprocess
from pathlib import Path

import numpy as np
import pytest
import trimesh
from PIL import Image

from neurender import io
from neurender.display import srgb
from neurender.simplification import (
    EXPORT_FILES,
    assets,
    bake,
    evaluate,
    export,
    formats,
    jobs,
    mesh_ops,
    render,
    terminator,
    user_mesh,
)

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]


def unit(x):
    return x / np.linalg.norm(x, axis=-1, keepdims=True)


def test_tangents_run_along_u_with_the_handedness_of_the_images_up_direction():
    # A quad facing +z: top-left, top-right, bottom-right, bottom-left (y up).
    positions = np.array([[-1, 1, 0], [1, 1, 0], [1, -1, 0], [-1, -1, 0]], float)
    faces = np.array([[0, 3, 2], [0, 2, 1]])
    normals = np.tile([0.0, 0.0, 1.0], (4, 1))
    upright = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)  # v down the image
    tangents = export.vertex_tangents(positions, normals, upright, faces)
    np.testing.assert_allclose(tangents, np.tile([1.0, 0, 0, 1], (4, 1)), atol=1e-12)
    mirrored = upright * [-1, 1] + [1, 0]
    tangents = export.vertex_tangents(positions, normals, mirrored, faces)
    np.testing.assert_allclose(tangents, np.tile([-1.0, 0, 0, -1], (4, 1)), atol=1e-12)
    # Either way the bitangent cross(N, T) w points up the image (+y): glTF's "+Y is up".
    assert np.allclose(np.cross(normals, tangents[:, :3]) * tangents[:, 3:], [0, 1, 0])


@pytest.fixture
def sphere_atlas():
    """A coarse icosphere with an xatlas atlas, its welded normals and glTF tangents."""
    sphere = trimesh.creation.icosphere(1)
    low = mesh_ops.uv_atlas(np.asarray(sphere.vertices), np.asarray(sphere.faces), 32)
    atlas, normals = low.atlas_positions(), low.atlas_normals()
    tangents = export.vertex_tangents(atlas, normals, low.uvs, low.uv_faces)
    return low, atlas, normals, tangents


def random_normal_map(size, seed=0):
    rng = np.random.default_rng(seed)
    m = unit(rng.normal(size=(size, size, 3)) * [0.5, 0.5, 0.3] + [0, 0, 1])
    return (m + 1) / 2


def test_tangents_are_unit_orthogonal_to_the_normals_and_signed(sphere_atlas):
    _, _, normals, tangents = sphere_atlas
    np.testing.assert_allclose(np.linalg.norm(tangents[:, :3], axis=1), 1, atol=1e-9)
    np.testing.assert_allclose((tangents[:, :3] * normals).sum(1), 0, atol=1e-9)
    assert set(np.unique(tangents[:, 3])) <= {-1.0, 1.0}


def test_gltf_normal_map_gives_mitsubas_normal_where_a_viewer_shades(sphere_atlas):
    """At every covered texel centre, the normal a glTF viewer computes from the exported
    map (interpolated per-vertex T, B = cross(N, T) w and N, as the glTF Sample Viewer and
    three.js do) equals the normal Mitsuba shades with from the optimised map (its frame is
    checked against Mitsuba's BSDF in test_render.py)."""
    low, atlas, normals, tangents = sphere_atlas
    size = 32
    mitsuba_map = random_normal_map(size)
    change = export.frame_change(atlas, normals, tangents, low.uvs, low.uv_faces, size)
    gltf_map = export.to_gltf_normals(change, mitsuba_map)
    samples = bake.rasterise_uvs(low.uvs, low.uv_faces, size)
    # A texel on a shared edge belongs to the triangle rasterised last.
    texel = samples.rows * size + samples.cols
    _, last = np.unique(texel[::-1], return_index=True)
    keep = len(texel) - 1 - last
    samples = bake.TexelSamples(
        *(x[keep] for x in (samples.rows, samples.cols, samples.face, samples.bary))
    )
    _, s, t, n = bake.tangent_frames(atlas, normals, low.uvs, low.uv_faces, samples)
    m = mitsuba_map[samples.rows, samples.cols] * 2 - 1
    seen_by_mitsuba = unit(s * m[:, :1] + t * m[:, 1:2] + n * m[:, 2:])
    corners = low.uv_faces[samples.face]
    bitangents = np.cross(normals, tangents[:, :3]) * tangents[:, 3:]

    def viewer(x):
        return unit(np.einsum("kj,kjc->kc", samples.bary, x[corners]))

    g = gltf_map[samples.rows, samples.cols] * 2 - 1
    seen_by_viewer = unit(
        viewer(tangents[:, :3]) * g[:, :1]
        + viewer(bitangents) * g[:, 1:2]
        + viewer(normals) * g[:, 2:]
    )
    np.testing.assert_allclose(seen_by_viewer, seen_by_mitsuba, atol=1e-9)
    # The conversion is exactly invertible on every texel, covered or not.
    back = export.to_mitsuba_normals(change, gltf_map)
    np.testing.assert_allclose(back, (unit(mitsuba_map * 2 - 1) + 1) / 2, atol=1e-9)


def read_glb(path):
    """``(json, binary chunk)`` of a GLB file."""
    data = Path(path).read_bytes()
    magic, version, total = struct.unpack_from("<4sII", data)
    assert (magic, version, total) == (b"glTF", 2, len(data))
    length, kind = struct.unpack_from("<I4s", data, 12)
    assert kind == b"JSON"
    tree = json.loads(data[20 : 20 + length])
    bin_length, bin_kind = struct.unpack_from("<I4s", data, 20 + length)
    assert bin_kind == b"BIN\0"
    return tree, data[28 + length : 28 + length + bin_length]


def accessor(tree, binary, index):
    a = tree["accessors"][index]
    view = tree["bufferViews"][a["bufferView"]]
    dtype = {5126: np.float32, 5125: np.uint32, 5123: np.uint16}[a["componentType"]]
    width = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}[a["type"]]
    data = np.frombuffer(binary, dtype, a["count"] * width, view["byteOffset"])
    return data.reshape(a["count"], width)


def _entry(path) -> dict:
    return {"path": str(path), "ratio": 0.05, "triangles": None, "views": "all_around"}


@pytest.fixture(scope="module")
def exported(bumpy_glb, tmp_path_factory):
    """The trimesh-made bumpy asset through QEM, xatlas and the classic bakes (non-trivial
    albedo and normal maps), exported; ``(asset, low, albedo, normal map, folder)``."""
    asset = assets.user_asset({"case": "bumpy", "asset": _entry(bumpy_glb)})
    v, f = mesh_ops.decimate(asset.vertices, asset.faces, asset.triangles)
    low = mesh_ops.uv_atlas(v, f, 32)
    normal_map, albedo = bake.bake(low, asset.vertices, asset.faces, 32, asset.colour_fn)
    folder = tmp_path_factory.mktemp("export")
    formats.save_lowpoly(folder / "lowpoly.npz", low, asset.albedo, asset.to_asset)
    paths = {k: folder / name for k, name in EXPORT_FILES.items()}
    export.export(paths, low, low.positions, albedo, normal_map, asset.to_asset)
    return asset, low, albedo, normal_map, folder


def test_export_writes_its_files_in_the_assets_units_with_srgb_base_colour(exported, bumpy_glb):
    asset, low, albedo, _, folder = exported
    assert sorted(p.name for p in folder.iterdir()) == sorted(
        ["lowpoly.npz", *EXPORT_FILES.values()]
    )
    source = trimesh.load(bumpy_glb, force="mesh", process=False)
    again = trimesh.load(folder / EXPORT_FILES["glb"], force="mesh", process=False)
    # QEM keeps the silhouette: the bounding box is the source's, in its own units.
    np.testing.assert_allclose(again.bounds, source.bounds, atol=0.02 * np.ptp(source.bounds))
    stored = np.asarray(Image.open(folder / EXPORT_FILES["texture"]))
    np.testing.assert_array_equal(stored, io.to_uint8(srgb(albedo)))
    obj = trimesh.load(folder / EXPORT_FILES["obj"], force="mesh", process=False)
    np.testing.assert_allclose(np.sort(obj.vertices, 0), np.sort(again.vertices, 0), atol=1e-5)


def test_glb_holds_tangents_normal_texture_and_a_lambertian_material(exported):
    _, low, _, _, folder = exported
    tree, binary = read_glb(folder / EXPORT_FILES["glb"])
    primitive = tree["meshes"][0]["primitives"][0]
    material = tree["materials"][primitive["material"]]
    assert material["normalTexture"] == {"index": 1}
    assert material["extensions"]["KHR_materials_specular"]["specularFactor"] == 0.0
    assert material["pbrMetallicRoughness"]["metallicFactor"] == 0.0
    attributes = {k: accessor(tree, binary, i) for k, i in primitive["attributes"].items()}
    atlas, normals = low.atlas_positions(), low.atlas_normals()
    expected = export.vertex_tangents(atlas, normals, low.uvs, low.uv_faces)
    np.testing.assert_allclose(attributes["TANGENT"], expected, atol=1e-6)
    np.testing.assert_allclose(attributes["TEXCOORD_0"], low.uvs, atol=1e-7)
    np.testing.assert_allclose(attributes["NORMAL"], normals, atol=1e-6)
    faces = accessor(tree, binary, primitive["indices"]).reshape(-1, 3)
    np.testing.assert_array_equal(faces, low.uv_faces)


def test_exported_glb_and_obj_rerender_within_a_tenth_of_a_db(
    mitsuba, exported, stage_cfg, bumpy_glb
):
    """Read back with trimesh, rendered as the evaluation renders ours: the held-out PSNR
    against the asset's references equals that of the maps before export within 0.1 dB."""
    mi, dr = mitsuba
    _, low, albedo, normal_map, folder = exported
    test_views = jobs.case_views(stage_cfg, "bumpy", "test", "all_around")
    asset = assets.user_asset({**stage_cfg, "case": "bumpy", "asset": _entry(bumpy_glb)})
    references = asset.references(mi, test_views, "test")

    def psnr(shape):
        images = render.render_views(
            mi, shape, test_views, 32, 32, 70.0, 5, integrator=terminator.integrator(mi, dr)
        )
        return np.mean(
            [evaluate.image_metrics(a, b)["psnr"] for a, b in zip(images, references, strict=True)]
        )

    direct = psnr(render.atlas_shape(mi, low, render.material(mi, albedo, normal_map)))
    flat = psnr(render.atlas_shape(mi, low, render.material(mi, albedo)))
    assert direct > flat + 0.5  # the normal map matters, so a wrong frame would show
    for kind in ("glb", "obj"):
        again = psnr(
            evaluate.exported_shape(mi, folder / EXPORT_FILES[kind], folder / "lowpoly.npz")
        )
        assert abs(again - direct) < 0.1, kind


@pytest.fixture(scope="module")
def far_away(tmp_path_factory):
    """A 2 m rock in georeferenced coordinates (UTM, metres, as scans are exported) through
    the stage's normalisation, QEM and xatlas, exported with flat maps;
    ``(stage-frame atlas mesh, to_asset, folder)``."""
    folder = tmp_path_factory.mktemp("far")
    rock = trimesh.creation.icosphere(3)
    source = folder / "utm.obj"  # float64 digits (trimesh writes PLY in float32)
    utm = rock.vertices + [512345.0, 5412345.0, 230.0]
    lines = [f"v {x:.17g} {y:.17g} {z:.17g}" for x, y, z in utm]
    source.write_text("\n".join(lines + [f"f {a} {b} {c}" for a, b, c in rock.faces + 1]))
    mesh = user_mesh.load(source)
    scale, offset = assets.normalisation(mesh)
    stage = mesh.transformed(scale, offset)
    low = mesh_ops.uv_atlas(*mesh_ops.decimate(stage.vertices, stage.faces, 200), 16)
    to_asset = assets.to_asset_matrix(scale, offset)
    paths = {k: folder / name for k, name in EXPORT_FILES.items()}
    flat = np.broadcast_to([0.5, 0.5, 1.0], (16, 16, 3))
    export.export(paths, low, low.positions, np.full((16, 16, 3), 0.5), flat, to_asset)
    return low, to_asset, folder


def test_an_asset_far_from_the_origin_reads_back_in_its_own_place(far_away):
    """Read back, the GLB (node translation applied) and the OBJ hold the asset's vertices,
    in its units and place, to float32's precision of its own size, as an asset about the
    origin does (float32 coordinates at y ~ 5.4e6 m are 0.5 m apart on a 2 m rock)."""
    low, to_asset, folder = far_away
    paths = {k: folder / name for k, name in EXPORT_FILES.items()}
    world = low.atlas_positions() @ to_asset[:3, :3].T + to_asset[:3, 3]
    size = np.ptp(world, axis=0).max()
    for kind in ("glb", "obj"):
        again = trimesh.load(paths[kind], force="mesh", process=False)
        assert np.abs(np.sort(again.vertices, 0) - np.sort(world, 0)).max() < 1e-6 * size, kind
        back, _, _ = export.reimport(paths[kind], to_asset)  # into the stage's frame
        stage_size = np.ptp(low.positions, axis=0).max()
        error = np.abs(back.atlas_positions() - low.atlas_positions()).max()
        assert error < 1e-6 * stage_size, kind
    tree, _ = read_glb(paths["glb"])
    assert np.abs(np.array(tree["nodes"][0]["translation"]) - world.mean(0)).max() < size


def gltf_validator() -> str | None:
    """The Khronos ``gltf-validator`` npm package's folder: ``$GLTF_VALIDATOR``, the
    repository's ``node_modules`` or npm's global root."""
    candidates = [
        os.environ.get("GLTF_VALIDATOR", ""),
        str(ROOT / "node_modules" / "gltf-validator"),
    ]
    if shutil.which("npm"):
        run = subprocess.run(["npm", "root", "-g"], capture_output=True, text=True, timeout=60)
        candidates.append(str(Path(run.stdout.strip()) / "gltf-validator"))
    return next((c for c in candidates if c and (Path(c) / "package.json").is_file()), None)


@pytest.mark.parametrize("case", ["exported", "far_away"])
def test_khronos_gltf_validator_finds_no_issue(case, request):
    if shutil.which("node") is None:
        pytest.skip("node is not installed (the Khronos glTF validator runs on node)")
    package = gltf_validator()
    if package is None:
        pytest.skip("npm package gltf-validator not found (npm install --no-save gltf-validator)")
    glb = request.getfixturevalue(case)[-1] / EXPORT_FILES["glb"]
    run = subprocess.run(
        ["node", str(HERE / "gltf_validate.js"), package, str(glb)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert run.returncode == 0, run.stderr
    issues = json.loads(run.stdout)["issues"]
    counts = {k: issues[k] for k in ("numErrors", "numWarnings", "numInfos", "numHints")}
    assert counts == dict.fromkeys(counts, 0), issues["messages"]
