"""The metaballs' learning-curve study (benchmarks/metaball_learning_curve.py) on tiny data:
its runs, its prefix of the largest train split, its rows and its merge."""

import json
from pathlib import Path

import pandas as pd
import pytest
import yaml

from neurender.metaballs import jobs

from . import scripts

ROOT = Path(__file__).resolve().parents[2]
curve = scripts.load("metaball_learning_curve")

TINY_CONFIG = {
    "device": "cpu",
    "metaballs": {"width": 32, "examples": {"train": 3, "val": 2, "test": 2}, "balls": [2, 4]},
    "metaballs_model": {"ngf": 4, "ndf": 4, "batch_size": 2},
}
TINY_STUDY = {
    "variant": "pix2pix",
    "examples": {"examples": [4, 8], "epochs": 1},
    "epochs": {"epochs": [1, 2], "examples": 4},
}


def test_the_committed_study_trains_each_run_once_at_the_default_configs_settings():
    study = yaml.safe_load((ROOT / "config/studies/metaballs_learning_curve.yaml").read_text())
    runs = curve.study_runs(study)
    labels = [r.label for r in runs]
    assert labels == [
        "600x2",
        "1200x2",
        "2400x2",
        "4800x2",
        "9600x2",
        "1200x1",
        "1200x4",
        "1200x8",
        "1200x16",
        "4800x8",
    ]
    config = curve.pipeline_config([])
    # the default run's pix2pix: only the epochs change from run to run
    params = curve.train_params(config, "pix2pix", 8)
    assert params["epochs"] == 8 and params["variant"] == "pix2pix"
    default = curve.train_params(config, "pix2pix", config["metaballs_model"]["epochs"])
    assert {k: v for k, v in params.items() if k != "epochs"} == {
        k: v for k, v in default.items() if k != "epochs"
    }
    assert (params["ngf"], params["ndf"], params["lr"], params["batch_size"]) == (16, 16, 5e-4, 4)
    assert params["flips"] is True and params["lr_schedule"] == "cosine"
    assert config["metaballs"]["examples"] == {"train": 1200, "val": 100, "test": 300}


def test_a_run_is_examples_x_epochs():
    assert curve.Run.parse("1200x8") == curve.Run(1200, 8)
    for bad in ("1200", "0x2", "ax2"):
        with pytest.raises(ValueError, match="run"):
            curve.Run.parse(bad)


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """A tiny config and study files, their data (train split of 8) and config."""
    root = tmp_path_factory.mktemp("curve")
    (root / "config.yaml").write_text(yaml.safe_dump(TINY_CONFIG))
    (root / "study.yaml").write_text(yaml.safe_dump(TINY_STUDY))
    common = ["--study", str(root / "study.yaml"), "--configfile", str(root / "config.yaml")]
    curve.main(["data", "--data", str(root / "data"), "--workers", "1", *common])
    return root, common, curve.pipeline_config([str(root / "config.yaml")])


def test_the_data_step_makes_the_largest_split_and_the_configs_val_and_test(tiny):
    root, _, config = tiny
    record = json.loads((root / "data" / "data.json").read_text())
    counts = {s: record["params"][s]["examples"] for s in ("train", "val", "test")}
    assert counts == {"train": 8, "val": 2, "test": 2}
    assert record["params"]["test"] == curve.examples_params(config, "test", 2)
    assert len(list((root / "data" / "train").glob("example_*.png"))) == 8


def test_a_prefix_of_the_largest_split_is_a_fresh_split_of_its_size(tiny, tmp_path):
    root, _, config = tiny
    prefix = curve.prefix_split(root / "data", 4, tmp_path / "prefix")
    fresh = curve.split_files(tmp_path / "fresh", "train")
    jobs.metaballs_examples({}, fresh, curve.examples_params(config, "train", 4), 1)
    pngs = sorted(Path(fresh["examples"]).iterdir())
    assert [p.name for p in pngs] == [f"example_{i:05d}.png" for i in range(4)]
    assert sorted(p.name for p in Path(prefix["train_dir"]).iterdir()) == [p.name for p in pngs]
    for png in pngs:
        assert (Path(prefix["train_dir"]) / png.name).read_bytes() == png.read_bytes()
    ours, theirs = (
        pd.read_csv(f).drop(columns="seconds")
        for f in (prefix["train_manifest"], fresh["manifest"])
    )
    pd.testing.assert_frame_equal(ours, theirs)
    pd.testing.assert_frame_equal(pd.read_csv(prefix["train_balls"]), pd.read_csv(fresh["balls"]))
    with pytest.raises(ValueError, match="8 examples; 9 wanted"):
        curve.prefix_split(root / "data", 9, tmp_path / "more")


def test_runs_give_one_row_per_measurement_and_merge_into_the_study(tiny, tmp_path):
    root, common, _ = tiny
    data = ["--data", str(root / "data"), "--work", str(tmp_path / "work")]
    first, second = tmp_path / "a.csv", tmp_path / "b.csv"
    curve.main(["run", *data, *common, "--runs", "8x1", "4x1", "--out", str(first)])
    curve.main(["run", *data, *common, "--runs", "4x2", "--out", str(second)])
    table = pd.read_csv(first)
    assert list(table.columns) == curve.COLUMNS
    keys = ["examples", "epochs", "model", "metric"]
    assert not table.duplicated(keys).any()
    # the baseline once, first, then the runs by examples and epochs
    runs = table[["examples", "epochs", "model"]].drop_duplicates().values.tolist()
    assert runs == [[0, 0, "isolated spheres"], [4, 1, "pix2pix"], [8, 1, "pix2pix"]]
    # each run's values are its evaluation's metrics.csv, the baseline's too
    for run in ("8x1", "4x1"):
        metrics = pd.read_csv(tmp_path / "work" / run / "evaluation" / "metrics.csv")
        n, e = map(int, run.split("x"))
        for model, (rn, re) in (("pix2pix", (n, e)), ("isolated spheres", (0, 0))):
            want = metrics[metrics.model == model].set_index("metric")["value"]
            mine = table[(table.model == model) & (table.examples == rn) & (table.epochs == re)]
            assert mine.set_index("metric")["value"].to_dict() == pytest.approx(want.to_dict())
    trained = table[table.model == "pix2pix"]
    assert (
        trained.query("metric == 'epochs'")["value"]
        == trained.query("metric == 'epochs'")["epochs"]
    ).all()
    assert (trained["train_seconds"] > 0).all() and (
        table.query("examples == 0").train_seconds == 0
    ).all()
    sidecar = json.loads(first.with_suffix(".json").read_text())
    assert set(sidecar["seconds"]) == {"8x1_train", "8x1_evaluate", "4x1_train", "4x1_evaluate"}
    assert sidecar["train_params"]["ngf"] == 4 and "epochs" not in sidecar["train_params"]

    out = tmp_path / "merged.csv"
    study = ["--study", str(root / "study.yaml")]
    curve.main(["merge", str(first), str(second), *study, "--out", str(out)])
    merged = pd.read_csv(out)
    assert not merged.duplicated(keys).any()
    runs = merged[["examples", "epochs"]].drop_duplicates().values.tolist()
    assert runs == [[0, 0], [4, 1], [4, 2], [8, 1]]
    base = table[table.model == "isolated spheres"]
    parts = [base, table[table.model == "pix2pix"], pd.read_csv(second).query("examples > 0")]
    assert len(merged) == sum(len(p) for p in parts)
    pd.testing.assert_frame_equal(merged.query("examples == 0").reset_index(drop=True), base)
    record = json.loads(out.with_suffix(".json").read_text())
    steps = [
        r["command"].split("metaball_learning_curve.py ")[1].split()[0] for r in record["runs"]
    ]
    assert steps == ["data", "run", "run"]
    assert out.with_suffix(".png").stat().st_size > 0
    verdict = curve.beats(merged, "pix2pix")
    assert len(verdict) == 3 * len(curve.SHOWN) and verdict["better"].dtype == bool

    # a later run extends the merged study: its steps kept, the data step listed once
    third = tmp_path / "c.csv"
    curve.main(["run", *data, *common, "--runs", "8x2", "--out", str(third)])
    again = tmp_path / "again.csv"
    curve.main(["merge", str(out), str(third), *study, "--out", str(again)])
    extended = pd.read_csv(again)
    runs = extended[["examples", "epochs"]].drop_duplicates().values.tolist()
    assert runs == [[0, 0], [4, 1], [4, 2], [8, 1], [8, 2]]
    pd.testing.assert_frame_equal(extended.query("not (examples == 8 and epochs == 2)"), merged)
    later = json.loads(again.with_suffix(".json").read_text())["runs"]
    assert later[:3] == record["runs"] and len(later) == 4
    assert "--runs 8x2" in later[3]["command"]


def _rows(examples, epochs, model, values):
    return pd.DataFrame(
        [
            dict(
                examples=examples, epochs=epochs, model=model, metric=m, value=v, train_seconds=1.0
            )
            for m, v in values.items()
        ]
    )


def test_a_merge_refuses_disagreeing_baselines_and_a_run_twice():
    base = _rows(0, 0, "isolated spheres", {"iou_depth": 0.5})
    mine = _rows(4, 1, "pix2pix", {"iou_depth": 0.6})
    other = _rows(8, 1, "pix2pix", {"iou_depth": 0.7})
    merged = curve.merge_tables([pd.concat([base, other]), pd.concat([base, mine])])
    assert merged[["examples", "model"]].values.tolist() == [
        [0, "isolated spheres"],
        [4, "pix2pix"],
        [8, "pix2pix"],
    ]
    # the first table's baseline is kept when another's differs by float rounding only
    rounded = base.assign(value=0.5 * (1 + 1e-6))
    kept = curve.merge_tables([pd.concat([base, mine]), pd.concat([rounded, other])])
    assert kept.query("examples == 0")["value"].tolist() == [0.5]
    moved = base.assign(value=0.51)
    with pytest.raises(ValueError, match="isolated spheres rows differ"):
        curve.merge_tables([pd.concat([base, mine]), pd.concat([moved, other])])
    with pytest.raises(ValueError, match=r"runs \['4x1'\] are in more than one table"):
        curve.merge_tables([pd.concat([base, mine]), pd.concat([base, mine])])


def test_beats_compares_each_metric_in_its_direction():
    base = _rows(0, 0, "isolated spheres", {"iou_depth": 0.5, "normal_error_median_deg": 10.0})
    mine = _rows(4, 1, "pix2pix", {"iou_depth": 0.6, "normal_error_median_deg": 12.0})
    verdict = curve.beats(pd.concat([base, mine]), "pix2pix").set_index("metric")
    assert (
        verdict.loc["iou_depth", "better"] and not verdict.loc["normal_error_median_deg", "better"]
    )
    assert verdict.loc["normal_error_median_deg", "baseline"] == 10.0
