"""The simplification viewer and mesh figure: the reference as the asset's own surface and
materials, the variants as the evaluation draws them with their triangle counts and PSNR,
and both jobs on a user asset as the workflow calls them."""

import io as _io

import numpy as np
import pandas as pd
import trimesh
from PIL import Image

from neurender import viewer_data
from neurender.simplification import CASE_FILES, EXPORT_FILES, assets, jobs, viewer
from neurender.simplification.user_mesh import Part


def _load(glb_b64: str) -> trimesh.Scene:
    return trimesh.load(_io.BytesIO(viewer_data.decode_array(glb_b64, "u1").tobytes()), "glb")


def test_vertex_corners_give_each_vertex_its_own_position():
    faces = np.array([[0, 1, 2], [2, 3, 0], [3, 4, 2]])
    vertices = np.random.default_rng(0).random((6, 3))
    face, bary = viewer.vertex_corners(faces, 6)
    at = np.einsum("vj,vjc->vc", bary, vertices[faces[face]])
    np.testing.assert_allclose(at[:5], vertices[:5])
    assert face[5] == 0  # unused: the first face's first corner


def test_face_coloured_parts_keep_one_colour_per_face():
    part = Part(
        np.eye(3) * [1, 2, 3],
        np.array([[0, 1, 2]]),
        np.ones(3),
        face_colours=np.array([[0.2, 0.4, 0.6]]),
    )
    primitive = viewer.part_primitive(part, np.tile([0.0, 0.0, 1.0], (3, 1)))
    np.testing.assert_array_equal(primitive.colours, np.tile([0.2, 0.4, 0.6], (3, 1)))
    np.testing.assert_array_equal(primitive.positions[primitive.faces[0]], part.vertices)


def test_the_metaball_reference_carries_the_field_colour_per_vertex():
    cfg = {"metaball_count": 3, "metaball_grid": 16, "metaball_triangles": 50, "seed": 0}
    asset = assets.load("metaballs", cfg)
    assert asset.albedo is None  # the balls' colours vary
    (primitive,) = viewer.reference_primitives(asset)
    face, bary = viewer.vertex_corners(asset.faces, len(asset.vertices))
    np.testing.assert_allclose(
        primitive.colours, np.clip(asset.colour_fn(asset.vertices, face, bary), 0, 1)
    )
    assert primitive.colours.std(0).max() > 0.01  # the balls' colours differ
    (head,) = viewer.reference_primitives(
        assets.load("head", {"head_vertices": 200, "head_triangles": 40, "seed": 0})
    )
    assert head.base_colour == (0.8, 0.8, 0.8) and head.colours is None


def _simplified(bumpy_glb, cfg, tmp):
    """The bumpy user asset through prepare, optimise, deploy and evaluate: its files, the
    mean metrics table and the params of the viewer jobs."""
    case = tmp / "bumpy"
    entry = {"path": str(bumpy_glb), "ratio": 0.05, "triangles": None, "views": "all_around"}
    files = {k: str(case / v) for k, v in {**CASE_FILES, **EXPORT_FILES}.items()}
    prepared = {
        "train_images": str(case / "reference_train.exr"),
        "train_views": str(case / "views_train.csv"),
    } | {k: files[k] for k in ("test_images", "test_views", "lowpoly", "baked_normal")}
    prepared |= {"baked_albedo": files["baked_albedo"], "stats": str(case / "stats.csv")}
    params = {**cfg, "case": "bumpy", "asset": entry}
    jobs.simplification_prepare({"asset": str(bumpy_glb)}, prepared, params, 1)
    optimised = {k: files[k] for k in ("mesh", "normal", "albedo", "loss")}
    inputs = {**prepared, "initial_albedo": files["baked_albedo"]}
    jobs.simplification_optimise(inputs, optimised, {**cfg, "case": "bumpy"}, 1)
    deployed = {**{k: files[k] for k in EXPORT_FILES}, "table": str(case / "deployment.csv")}
    jobs.simplification_deploy({**prepared, **optimised}, deployed, {"case": "bumpy"}, 1)
    evaluated = {k: str(tmp / f"{k}.csv") for k in ("metrics", "metrics_views")}
    evaluated |= {"figure": str(tmp / "c.png"), "loss_figure": str(tmp / "l.png")}
    keyed = {f"bumpy_{k}": v for k, v in files.items()}
    jobs.simplification_evaluate(keyed, evaluated, {**cfg, "cases": ["bumpy"]}, 1)
    return files, evaluated["metrics"], {"seed": cfg["seed"], "case": "bumpy", "asset": entry}


def test_the_viewer_and_figure_jobs_show_reference_and_variants(bumpy_glb, stage_cfg, tmp_path):
    files, metrics, params = _simplified(bumpy_glb, stage_cfg, tmp_path)
    inputs = {"asset": str(bumpy_glb), "metrics": metrics} | files
    jobs.simplification_viewer(inputs, {"viewer": tmp_path / "v.json"}, params, 1)
    viewer_file = viewer_data.read(tmp_path / "v.json")
    data = viewer_file["data"]
    assert viewer_file["kind"] == "meshes"
    assert list(data["meshes"]) == ["reference", "QEM", "classic bake", "ours"]
    table = pd.read_csv(metrics)
    psnr = table[table.metric == "psnr"].set_index("model")["value"]
    for label, variant in (("QEM", "qem"), ("classic bake", "baked"), ("ours", "ours")):
        assert f"PSNR {psnr[variant]:.1f} dB" in data["captions"][label]
    source = trimesh.load(bumpy_glb, force="mesh", process=False)
    reference = _load(data["meshes"]["reference"]).to_mesh()
    assert len(reference.faces) == len(source.faces) == 5120
    assert data["captions"]["reference"] == "5,120 triangles"
    ours = _load(data["meshes"]["ours"]).to_mesh()
    np.testing.assert_allclose(  # the optimised vertices, in the stage's frame
        np.sort(np.unique(ours.vertices.round(5), axis=0), 0),
        np.sort(np.unique(np.load(files["mesh"])["positions"].round(5), axis=0), 0),
        atol=1e-4,
    )
    assert f"{len(ours.faces)} triangles" in data["captions"]["ours"]

    figure = {"asset": str(bumpy_glb), "lowpoly": files["lowpoly"], "mesh": files["mesh"]}
    jobs.simplification_mesh_figure(figure, {"png": tmp_path / "meshes.png"}, params, 1)
    image = np.asarray(Image.open(tmp_path / "meshes.png").convert("RGB"))
    assert image.shape == (400, 1100, 3)
    for k in range(3):  # every panel draws its mesh on the white background
        cell = image[40:, k * 366 : (k + 1) * 366]
        assert (cell.sum(-1) < 600).mean() > 0.02, k


def test_a_reference_over_the_budget_is_shown_decimated(monkeypatch):
    monkeypatch.setattr(viewer, "MAX_REFERENCE_TRIANGLES", 100)
    asset = assets.load("head", {"head_vertices": 200, "head_triangles": 40, "seed": 0})
    (primitive,) = viewer.reference_primitives(asset)
    assert len(primitive.faces) <= 100 < len(asset.faces)
    assert primitive.base_colour == (0.5, 0.5, 0.5)
