"""NDR's data, evaluation, relighting and targets jobs as the workflow calls them, on two
16-pixel samples (the equal-quality, deploy, viewer and training jobs: their own files)."""

import numpy as np
import pandas as pd
import pytest
import torch
from PIL import Image

from neurender import io
from neurender.ndr import data, jobs, summary
from neurender.ndr.buffers import NDRDataset
from neurender.ndr.evaluate import NOISE_FLOOR, score_split
from neurender.ndr.model import SHADING_INPUT

from .test_equal_quality import CFG

TRAIN = {"seed": 0, "device": "cpu", "variant": "ndr", "mask_erosion": 1, "epochs": 1}
TRAIN |= {"batch_size": 2, "lr": 1e-3, "lr_schedule": "constant", "widths": [4, 8]}
TRAIN |= {"sh_hidden": 8, "shading_residual": True}


def _files(root, split: str) -> dict[str, str]:
    return {k: str(root / f"{split}_{k}") for k in ("dir", "manifest", "lighting")}


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    """The train and test splits of two samples each, rendered by the data job; NDR
    trained one epoch on them; its checkpoint and loss curve."""
    root = tmp_path_factory.mktemp("ndr_jobs")
    for split in ("train", "test"):
        files = _files(root, split)
        outputs = {"samples": files["dir"], "manifest": files["manifest"]}
        outputs["lighting"] = files["lighting"]
        jobs.ndr_data({}, outputs, CFG | {"split": split, "count": 2}, 1)
    split = {
        f"{part}_{k}": v for part in ("train", "val") for k, v in _files(root, "train").items()
    }
    model = {"checkpoint": str(root / "ndr.pt"), "loss": str(root / "ndr_loss.csv")}
    jobs.ndr_train(split, model, TRAIN, 1)
    return root, model


def test_the_data_job_renders_the_split_and_count_it_is_given(rendered, tmp_path):
    root, _ = rendered
    manifest = io.read_csv(_files(root, "test")["manifest"])
    assert len(manifest) == 2
    # The same split drawn by the data module itself: the job adds nothing of its own.
    files = _files(tmp_path, "test")
    data.generate_split(CFG, "test", 2, files["dir"], files["manifest"], files["lighting"], 1)
    job, direct = (NDRDataset.from_files(f, 0).buffers for f in (_files(root, "test"), files))
    assert job.keys() == direct.keys()
    for key in job:
        torch.testing.assert_close(job[key], direct[key], rtol=0, atol=0)


@pytest.fixture(scope="module")
def evaluated(rendered):
    """The evaluation job's outputs for NDR trained on the rendered splits."""
    root, model = rendered
    inputs = {f"test_{k}": v for k, v in _files(root, "test").items()}
    inputs |= {"train_manifest": _files(root, "train")["manifest"]}
    inputs |= {"checkpoint_ndr": model["checkpoint"], "loss_ndr": model["loss"]}
    outputs = {name: str(root / f"eval_{name}.csv") for name in ("metrics", "samples", "timing")}
    outputs |= {"figure": str(root / "comparison.png"), "curves": str(root / "curves.png")}
    params = {"device": "cpu", "variants": ["ndr"], "mask_erosion": 1}
    jobs.ndr_evaluate(inputs, outputs, params, 1)
    return outputs


def test_the_evaluation_scores_ndr_beside_its_baselines_and_times_it(rendered, evaluated):
    root, model = rendered
    metrics = io.read_csv(evaluated["metrics"])
    assert {"ndr", NOISE_FLOOR, SHADING_INPUT} <= set(metrics.model)
    # The table is the evaluation module's scores of the same split and checkpoint.
    test = NDRDataset.from_files(_files(root, "test"), 1)
    scored = score_split("complex", test, {"ndr": model["checkpoint"]}, torch.device("cpu"))
    pd.testing.assert_frame_equal(metrics, pd.DataFrame(scored.rows), check_dtype=False)
    timing = io.read_csv(evaluated["timing"]).set_index("metric")["value"]
    assert (timing.filter(like="seconds") > 0).all()
    for png in ("figure", "curves"):
        assert np.asarray(Image.open(evaluated[png]).convert("RGB")).std() > 1


def test_relighting_scores_ndr_and_the_shading_input_at_every_turn(rendered):
    root, model = rendered
    outputs = {"csv": str(root / "relight.csv"), "figure": str(root / "relight.png")}
    params = CFG | {"relight_sample": 0, "relight_turns": 2, "mask_erosion": 1}
    jobs.ndr_relight({"checkpoint": model["checkpoint"]}, outputs, params, 1)
    table = io.read_csv(outputs["csv"])
    assert set(table.model) == {"ndr", SHADING_INPUT}
    assert table.groupby(["model", "metric"]).size().eq(2).all()  # one row per turn
    assert (table[table.metric == "dssim_I_R"].value.between(0, 1)).all()


def test_targets_read_the_metrics_and_equal_quality_tables_only(evaluated, tmp_path):
    """The job's table is the summary's targets of its two inputs, whatever its params and
    threads (it reads no benchmark file and no core count)."""
    equal = pd.DataFrame(
        columns=["method", "dataset", "model", "split", "setting", "bound", "metric", "value"]
    )
    io.write_csv(tmp_path / "equal.csv", equal)
    inputs = {"metrics": evaluated["metrics"], "equal_quality": str(tmp_path / "equal.csv")}
    jobs.ndr_targets(inputs, {"targets": str(tmp_path / "targets.csv")}, {}, 2)
    metrics = io.read_csv(evaluated["metrics"])
    expected = summary.targets(metrics, equal)
    pd.testing.assert_frame_equal(
        io.read_csv(tmp_path / "targets.csv"), expected, check_dtype=False
    )
    # The shading input's and the noise floor's rows: NDR's DSSIM against theirs.
    ndr = metrics.query("model == 'ndr' and metric == 'dssim_I_R'").value.iloc[0]
    floor = metrics.query("model == @NOISE_FLOOR and metric == 'dssim_I_R'").value.iloc[0]
    row = expected.set_index("subject").loc[NOISE_FLOOR]
    assert row.measured == pytest.approx(floor / ndr) and row.met == (floor < ndr)
    assert "stage" not in set(expected.subject)


def test_the_data_summary_counts_each_splits_samples_and_runs_the_furnace_checks(rendered):
    root, _ = rendered
    splits = ["train", "test"]
    inputs = {"manifests": [_files(root, s)["manifest"] for s in splits]}
    inputs["example"] = _files(root, "test")["dir"]
    outputs = {"csv": str(root / "data.csv"), "furnace": str(root / "furnace.csv")}
    outputs["figure"] = str(root / "buffers.png")
    params = {"splits": splits, "device": "cpu", "width": 16, "furnace_spp": 16}
    params |= {"coarse_samples": 16, "seed": 5, "coarse_height": 8}
    jobs.ndr_summary(inputs, outputs, params, 1)
    table = io.read_csv(outputs["csv"])
    samples = table[table.metric == "samples"].set_index("split")["value"]
    assert samples.to_dict() == {"train": 2, "test": 2}
    furnace = io.read_csv(outputs["furnace"])
    assert len(furnace) > 0 and furnace.measured.notna().all()
    assert np.asarray(Image.open(outputs["figure"]).convert("RGB")).std() > 1


def test_your_objects_are_rendered_under_the_test_and_real_world_maps_and_scored(
    rendered, tmp_path
):
    import trimesh

    _, model = rendered
    ring = trimesh.creation.annulus(r_min=0.3, r_max=1.0, height=0.6)
    ring.export(tmp_path / "ring.glb")
    params = CFG | {"user_objects": {"ring": str(tmp_path / "ring.glb")}, "mask_erosion": 1}
    params |= {"user_object_defaults": {"base_colour": [0.8, 0.8, 0.8], "specular": 0.04}}
    params["user_object_defaults"]["roughness"] = 0.5
    params |= {"user_object_maps": 1, "test_samples": 2, "sunlit_samples": 1}
    outputs = {"maps": str(tmp_path / "maps.csv"), "table": str(tmp_path / "objects.csv")}
    outputs["figure"] = str(tmp_path / "objects.png")
    jobs.ndr_user_objects({"checkpoint": model["checkpoint"]}, outputs, params, 1)
    per_map = io.read_csv(outputs["maps"])
    # One test map and one real-world-like map, NDR and the shading input on each.
    assert per_map.groupby("model").map.nunique().to_dict() == {"ndr": 2, SHADING_INPUT: 2}
    means = io.read_csv(outputs["table"])
    dssim = per_map[per_map.metric == "dssim_I_R"]
    want = dssim.groupby(["model", "split"]).value.mean()  # the split: the map set
    got = means[means.metric == "dssim_I_R"].set_index(["model", "split"]).value
    pd.testing.assert_series_equal(got.sort_index(), want.sort_index(), check_names=False)
    assert np.asarray(Image.open(outputs["figure"]).convert("RGB")).std() > 1
    with pytest.raises(ValueError, match="ndr.user_objects is empty"):
        jobs.ndr_user_objects({}, outputs, params | {"user_objects": {}}, 1)
