"""A user asset through the stage's jobs as the workflow calls them, and a bad asset
stopping the first job before it writes anything."""

import numpy as np
import pandas as pd
import pytest
import trimesh

from neurender.asset_files import AssetFileError
from neurender.simplification import CASE_FILES, EXPORT_FILES, jobs

PREPARED = {
    "train_images": "reference_train.exr",
    "test_images": "reference_test.exr",
    "train_views": "views_train.csv",
    "test_views": "views_test.csv",
    "lowpoly": "lowpoly.npz",
    "baked_normal": "baked_normal.png",
    "baked_albedo": "baked_albedo.png",
    "stats": "stats.csv",
}
OPTIMISED = {
    "mesh": "optimised.npz",
    "normal": "optimised_normal.png",
    "albedo": "optimised_albedo.png",
    "loss": "loss.csv",
}
DEPLOYED = {**EXPORT_FILES, "table": "deployment.csv"}


def entry(path, **keys):
    return {"path": str(path), "ratio": 0.05, "triangles": None, "views": "all_around", **keys}


def test_a_user_asset_runs_through_prepare_optimise_deploy_and_evaluate(
    bumpy_glb, stage_cfg, tmp_path
):
    case = tmp_path / "bumpy"
    case.mkdir()
    prepared = {k: str(case / v) for k, v in PREPARED.items()}
    params = {**stage_cfg, "case": "bumpy", "asset": entry(bumpy_glb)}
    jobs.simplification_prepare({"asset": str(bumpy_glb)}, prepared, params, 1)
    stats = pd.read_csv(prepared["stats"]).set_index("quantity")["value"]
    assert stats["reference_triangles"] == 5120 and stats["lowpoly_triangles"] <= 256
    optimised = {k: str(case / v) for k, v in OPTIMISED.items()}
    inputs = {**prepared, "initial_albedo": prepared["baked_albedo"]}
    jobs.simplification_optimise(inputs, optimised, {**stage_cfg, "case": "bumpy"}, 1)
    deployed = {k: str(case / v) for k, v in DEPLOYED.items()}
    jobs.simplification_deploy({**prepared, **optimised}, deployed, {"case": "bumpy"}, 1)
    summary = {"stats": str(tmp_path / "stats.csv")}
    inputs = {"stats": [prepared["stats"]], "losses": [optimised["loss"]]}
    jobs.simplification_summary(inputs, summary, {}, 1)
    gathered = pd.read_csv(summary["stats"]).set_index("quantity")["value"]
    assert gathered["lowpoly_triangles"] == stats["lowpoly_triangles"]
    loss = pd.read_csv(optimised["loss"])
    assert gathered["optimise_seconds"] == pytest.approx(loss[loss.metric == "seconds"].value.sum())
    evaluated = {
        k: str(tmp_path / f"{k}.{ext}")
        for k, ext in (
            ("metrics", "csv"),
            ("metrics_views", "csv"),
            ("figure", "png"),
            ("loss_figure", "png"),
        )
    }
    files = {f"bumpy_{k}": str(case / v) for k, v in {**CASE_FILES, **EXPORT_FILES}.items()}
    jobs.simplification_evaluate(files, evaluated, {**stage_cfg, "cases": ["bumpy"]}, 1)
    metrics = pd.read_csv(evaluated["metrics"])
    psnr = metrics[metrics["metric"] == "psnr"].set_index("model")["value"]
    assert set(psnr.index) == {"qem", "baked", "ours", "ours_glb", "ours_obj"}
    assert abs(psnr["ours_glb"] - psnr["ours"]) < 0.1 and abs(psnr["ours_obj"] - psnr["ours"]) < 0.1
    equal = {"table": str(tmp_path / "equal_quality.csv"), "figure": str(tmp_path / "eq.png")}
    sweep = {f"bumpy_{k}": prepared[k] for k in ("test_views", "test_images", "lowpoly")}
    params = {
        **stage_cfg,
        "cases": ["bumpy"],
        "user_assets": {"bumpy": entry(bumpy_glb)},
        "equal_quality_multiples": [2, 1],
    }
    jobs.simplification_equal_quality({**sweep, "metrics": evaluated["metrics"]}, equal, params, 1)
    table = pd.read_csv(equal["table"])
    value = table.set_index(["model", "setting", "metric"])["value"]
    ours = stats["lowpoly_triangles"]
    classic = table[table.model == "classic"].pivot_table(
        index="setting", columns="metric", values="value", sort=False
    )
    assert list(classic.multiple) == [1, 2]  # by budget
    # The 1x budget is the evaluation's baked variant, made and rendered the same way.
    assert classic.triangles.iloc[0] == ours
    baked = metrics[metrics.model == "baked"].set_index("metric")["value"]
    for metric in ("psnr", "ssim", "flip", "coverage_error"):
        assert classic[metric].iloc[0] == pytest.approx(baked[metric], rel=1e-9)
    (row,) = table[(table.model == "ours") & (table.metric == "psnr")].itertuples()
    assert row.value == pytest.approx(psnr["ours"])
    ratio = value["ours", row.setting, "equal_quality_triangle_ratio"]
    picked = value["ours", row.setting, "equal_quality_reference_triangles"]
    assert picked == classic.triangles[row.setting] and ratio == pytest.approx(picked / ours)
    targets = {"targets": str(tmp_path / "targets.csv")}
    inputs = {"metrics": evaluated["metrics"], "equal_quality": equal["table"]}
    jobs.simplification_targets(inputs, targets, {}, 1)
    targets = pd.read_csv(targets["targets"])
    assert set(targets.subject) == {"bumpy"}
    (triangle_target,) = targets[targets.check.str.contains("fewer triangles")].itertuples()
    assert triangle_target.measured == pytest.approx(ratio)
    assert f"(against {row.setting}, {row.bound})" in triangle_target.check
    export_checks = targets[targets["check"].str.startswith("exported")]
    assert len(export_checks) == 2 and export_checks["met"].all()
    gain = targets[targets["check"].str.startswith("PSNR gain")].measured.iloc[0]
    assert gain == pytest.approx(psnr["ours"] - psnr["qem"])


@pytest.mark.parametrize("problem", ["nan", "budget", "texture"])
def test_a_bad_asset_stops_prepare_before_any_output(stage_cfg, tmp_path, problem):
    box = trimesh.creation.box().subdivide()
    if problem == "nan":
        box.vertices[3] = np.nan
    box.export(tmp_path / "box.ply")
    asset = tmp_path / "box.ply"
    if problem == "texture":  # an OBJ whose MTL names a PNG that is not one
        box.visual = trimesh.visual.TextureVisuals(uv=box.vertices[:, :2] % 1.0)
        box.export(tmp_path / "box.obj")
        (tmp_path / "box.mtl").write_text("newmtl wood\nmap_Kd wood.png\n")
        (tmp_path / "wood.png").write_bytes(b"\x89PNG\r\n\x1a\n truncated")
        text = (tmp_path / "box.obj").read_text().splitlines()
        body = [line for line in text if not line.startswith(("mtllib", "usemtl"))]
        (tmp_path / "box.obj").write_text("\n".join(["mtllib box.mtl", "usemtl wood", *body]))
        asset = tmp_path / "box.obj"
    out = tmp_path / "out"
    out.mkdir()
    outputs = {k: str(out / v) for k, v in PREPARED.items()}
    params = {**stage_cfg, "case": "box", "asset": entry(asset, triangles=100)}
    message = {
        "nan": "not finite",
        "budget": "triangles = 100 gives a budget of 100",
        "texture": "names wood.png .*which could not be read",
    }[problem]
    with pytest.raises(AssetFileError, match=message):
        jobs.simplification_prepare({}, outputs, params, 1)
    assert list(out.iterdir()) == []
