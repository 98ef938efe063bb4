import numpy as np
import pandas as pd
from PIL import Image

from neurender import io
from neurender.equal_quality import LOWER, WITHIN
from neurender.metaballs import jobs, summary
from neurender.tables import TARGET_COLUMNS


def _metrics(rows):
    return pd.DataFrame(rows, columns=["model", "metric", "value"])


#: The columns of an equal-quality table (:func:`neurender.equal_quality.table`).
EQUAL_COLUMNS = ["method", "dataset", "model", "split", "setting", "bound", "metric", "value"]


def _equal(rows):
    """Equal-quality rows ``(model, setting, bound, metric, value)`` on the test set."""
    return pd.DataFrame(
        [("metaballs", "test", m, "equal quality", *rest) for m, *rest in rows],
        columns=EQUAL_COLUMNS,
    )


def test_targets_state_each_check_as_met_or_missed(tmp_path):
    metrics = _metrics(
        [
            ("good", "iou_depth", 0.99),
            ("good", "normal_error_mean_deg", 2.0),
            ("bad", "iou_depth", 0.5),
            ("bad", "normal_error_mean_deg", 40.0),
            ("isolated spheres", "iou_depth", 0.8),
            ("isolated spheres", "normal_error_mean_deg", 20.0),
            ("inflated spheres", "iou_depth", 0.85),
            ("inflated spheres", "normal_error_mean_deg", 10.0),
            ("good", "epochs", 2.0),  # a budget row: no score, no target
            ("bad", "epochs", 2.0),
        ]
    )
    timing = _metrics([("good", "speedup_at_145_balls", 50.0), ("good", "ms_per_frame", 1.0)])
    half = "step 1, 4 bisections, 0.5 width"
    equal = _equal(
        [
            ("good", half, WITHIN, "equal_quality_speedup", 6.0),
            ("good", half, WITHIN, "ms_per_frame", 1.0),
            ("bad", "step 1, 4 bisections, 1 width", LOWER, "equal_quality_speedup", 2.0),
        ]
    )
    table = summary.targets(metrics, timing, equal, width=128)
    # The job reads the three files and writes the same table.
    files = {name: tmp_path / f"{name}.csv" for name in ("metrics", "timing", "equal_quality")}
    for name, frame in zip(files, (metrics, timing, equal), strict=True):
        io.write_csv(files[name], frame)
    jobs.metaballs_targets(files, {"targets": tmp_path / "targets.csv"}, {"width": 128}, 1)
    pd.testing.assert_frame_equal(io.read_csv(tmp_path / "targets.csv"), table)
    assert list(table.columns) == list(TARGET_COLUMNS)
    # Baselines are not checked; the equal-quality targets' subject is the test set.
    assert set(table.subject) == {"good", "bad", "test"}
    assert not table.check.str.contains("epochs").any()
    assert table[table.subject == "good"].met.all()
    assert not table[table.subject == "bad"].met.any()
    speed_row = table[table.check.str.contains("faster than ray marching")]
    assert speed_row.measured.tolist() == [50.0]
    equal_rows = table[table.check.str.contains("cheapest ray marcher")]
    equal_rows = equal_rows.set_index(equal_rows.check.str.split().str[0])
    assert equal_rows.loc["good", "measured"] == 6.0 and equal_rows.loc["good", "met"]
    assert f"against {half}, within the sweep" in equal_rows.loc["good", "check"]
    # A lower bound of 2x: the true speed-up is at least 2x, which does not reach 5x.
    assert not equal_rows.loc["bad", "met"] and "lower bound" in equal_rows.loc["bad", "check"]


def test_paper_scale_targets_are_stricter():
    metrics = _metrics([("net", "iou_depth", 0.92), ("net", "normal_error_mean_deg", 10.0)])
    timing = _metrics([])
    equal = pd.DataFrame(columns=EQUAL_COLUMNS)
    default = summary.targets(metrics, timing, equal, width=128)
    paper = summary.targets(metrics, timing, equal, width=summary.PAPER_SCALE_WIDTH)
    checks = ["silhouette IoU", "mean normal error"]
    for check in checks:
        assert default[default.check.str.startswith(check)].met.all()
        assert not paper[paper.check.str.startswith(check)].met.any()


def test_data_rows_summarise_a_split():
    manifest = pd.DataFrame(
        {
            "split": ["val", "val"],
            "balls": [2, 4],
            "coverage": [0.1, 0.3],
            "min_depth_separation": [1.0, float("nan")],
            "seconds": [0.5, 1.5],
        }
    )
    rows = {r["metric"]: r["value"] for r in summary.data_rows(manifest)}
    assert rows == {
        "examples": 2.0,
        "balls_mean": 3.0,
        "coverage_mean": 0.2,
        "min_depth_separation_median": 1.0,
        "raymarch_seconds_per_example": 1.0,
    }


def test_every_network_is_checked_against_the_refined_impostors_and_they_are_not():
    metrics = _metrics(
        [
            ("net", "iou_depth", 0.97),
            ("net", "normal_error_mean_deg", 3.0),
            ("isolated spheres", "iou_depth", 0.8),
            ("isolated spheres", "normal_error_mean_deg", 20.0),
            ("refined spheres", "iou_depth", 0.96),
            ("refined spheres", "normal_error_mean_deg", 2.5),
        ]
    )
    full = "step 1, 4 bisections, 1 width"
    equal = _equal(
        [
            ("net", full, WITHIN, "equal_quality_speedup", 2.0),
            ("refined spheres", full, WITHIN, "equal_quality_speedup", 3.0),
        ]
    )
    table = summary.targets(metrics, _metrics([]), equal, width=128)
    # The baseline is compared with, never checked.
    assert set(table.subject) == {"net", "test"}
    assert not table.check.str.startswith("refined spheres").any()
    against = table[table.check.str.contains("refined spheres")].set_index("check")
    iou = "better than refined spheres (no learning) on iou_depth (0.96)"
    angle = "better than refined spheres (no learning) on normal_error_mean_deg (2.5)"
    assert against.loc[iou, "met"] and not against.loc[angle, "met"]
    assert against.loc[angle, "measured"] == 3.0


def test_the_count_of_empty_frames_is_no_score_to_beat():
    metrics = _metrics(
        [
            ("net", "iou_depth", 0.99),
            ("net", "normal_error_mean_deg", 2.0),
            ("net", "empty_frames", 1.0),
            ("isolated spheres", "iou_depth", 0.8),
            ("isolated spheres", "normal_error_mean_deg", 20.0),
            ("isolated spheres", "empty_frames", 1.0),
        ]
    )
    equal = pd.DataFrame(columns=EQUAL_COLUMNS)
    table = summary.targets(metrics, _metrics([]), equal, width=128)
    assert not table.check.str.contains("empty_frames").any()
    assert table.met.all()


def test_the_data_job_summarises_every_split_and_draws_the_first_examples(tmp_path, write_split):
    for split, count in (("train", 3), ("test", 2)):
        write_split(split, count)
    splits = ("train", "test")
    inputs = {
        "manifests": [str(tmp_path / f"{s}_manifest.csv") for s in splits],
        "examples": [str(tmp_path / s) for s in splits],
    }
    outputs = {"csv": tmp_path / "data.csv", "figure": tmp_path / "examples.png"}
    jobs.metaballs_summary(inputs, outputs, {}, 1)
    data = io.read_csv(outputs["csv"])
    examples = data[data.metric == "examples"].set_index("split")["value"]
    assert examples.to_dict() == {"train": 3, "test": 2}
    balls = data[data.metric == "balls_mean"].set_index("split")["value"]
    assert balls.between(2, 4).all()  # the scene keys' ball counts
    assert np.asarray(Image.open(outputs["figure"]).convert("RGB")).std() > 1
