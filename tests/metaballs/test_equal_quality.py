import math

import pandas as pd
import pytest
import torch

from neurender import equal_quality as shared
from neurender.metaballs import equal_quality as eq
from neurender.metaballs import raymarch, scenes

from .keys import KERNEL, THESIS_SCENES
from .tiny import train_variants, write_splits


def _scenes(count=3):
    gen = torch.Generator().manual_seed(5)
    return [scenes.sample_scene(12, (0.6, 1.6), gen).to(torch.float32) for _ in range(count)]


def test_the_finest_setting_is_the_reference_marcher():
    assert eq.sweep()[0] == eq.REFERENCE
    scene = _scenes(1)[0]
    ref = raymarch.render_gbuffers(scene, 32).stack()
    torch.testing.assert_close(eq.render(scene, 32, eq.REFERENCE), ref, atol=0, rtol=0)
    row = eq.score_settings([(scene, ref)], 32, [eq.REFERENCE]).iloc[0]
    assert row["iou_depth"] == 1.0 and row["normal_error_mean_deg"] == pytest.approx(0, abs=1e-3)


def test_a_lower_resolution_is_the_coarse_image_upsampled_by_nearest_neighbour():
    scene = _scenes(1)[0]
    coarse = raymarch.render_gbuffers(scene, 16).stack()
    half = eq.render(scene, 32, eq.March(resolution=0.5))
    torch.testing.assert_close(half[:, ::2, ::2], coarse, atol=0, rtol=0)
    torch.testing.assert_close(half[:, 1::2, 1::2], coarse, atol=0, rtol=0)
    with pytest.raises(ValueError, match="resolution 1.5"):
        eq.render(scene, 32, eq.March(resolution=1.5))


def test_quality_falls_along_each_knob_so_the_cheapest_can_be_picked():
    width = 32
    examples = [(s, raymarch.render_gbuffers(s, width).stack()) for s in _scenes()]
    knobs = {
        "resolution": [eq.March(resolution=r) for r in (1.0, 0.5, 0.25)],
        "min_step": [eq.March(min_step=m) for m in (0.02, 1.0, 3.0)],
        # with the reference's step floor the bracket is too short for bisections to matter
        "bisections": [eq.March(min_step=1.0, bisections=b) for b in (24, 4, 0)],
    }
    for knob, settings in knobs.items():
        scores = eq.score_settings(examples, width, settings)
        iou, normal = scores["iou_depth"], scores["normal_error_mean_deg"]
        assert iou.is_monotonic_decreasing, (knob, iou.tolist())
        assert normal.is_monotonic_increasing, (knob, normal.tolist())
        assert normal.iloc[-1] > normal.iloc[0], (knob, normal.tolist())
        # so each coarser setting reaches the quality of the next finer one's, not conversely
        for finer, coarser in zip(scores.index[:-1], scores.index[1:], strict=True):
            target = scores.loc[coarser, list(eq.QUALITY)].to_dict()
            assert shared.reaches(scores.loc[[finer]], target, eq.QUALITY).all()


def _synthetic():
    return pd.DataFrame(
        {
            "label": [eq.REFERENCE.label, "fast but blurry", "middle", "tie", "slow"],
            "resolution": [1.0, 0.25, 0.5, 0.5, 1.0],
            "ms_per_frame": [100.0, 5.0, 20.0, 30.0, 80.0],
            "iou_depth": [1.0, 0.80, 0.93, 0.95, 0.99],
            "normal_error_mean_deg": [0.2, 3.0, 7.8, 7.0, 1.0],
        }
    )


def test_the_pick_is_the_shared_rule_on_both_metrics(tmp_path):
    scores = _synthetic()
    target = {"iou_depth": 0.93, "normal_error_mean_deg": 7.8}  # "middle" meets it exactly
    assert eq.cheapest(scores, target) == shared.Pick("middle", 20.0, shared.WITHIN)
    stricter = {"iou_depth": 0.94, "normal_error_mean_deg": 7.8}
    assert eq.cheapest(scores, stricter) == shared.Pick("tie", 30.0, shared.WITHIN)
    unreachable = {"iou_depth": 1.0, "normal_error_mean_deg": 0.1}
    assert eq.cheapest(scores, unreachable) == shared.Pick(eq.REFERENCE.label, 100.0, shared.LOWER)
    path = tmp_path / "quality.png"
    eq.quality_figure(scores, {"ours": (target, 4.0)}, str(path))
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_network_time_is_the_inputs_plus_the_network():
    calls = []
    ms = eq.network_ms_per_frame(
        lambda s: calls.append("draw") or torch.zeros(4, 8, 8),
        lambda x: calls.append(tuple(x.shape)) or x,
        _scenes(2),
        repeats=2,
    )
    assert ms > 0
    assert calls.count("draw") == 2 * 3 and calls.count((1, 4, 8, 8)) == 2 * 3  # warm-up + 2


def test_the_table_names_each_networks_pick_and_speedups():
    target = {"iou_depth": 0.93, "normal_error_mean_deg": 7.8}
    perfect = {"iou_depth": 1.0, "normal_error_mean_deg": 0.1}
    rows = eq.table(_synthetic(), {"ours": (target, 4.0), "perfect": (perfect, 2.0)})
    value = rows.set_index(["model", "setting", "metric"])["value"]
    assert value["ours", "middle", "equal_quality_speedup"] == pytest.approx(5.0)
    assert value["ours", "middle", "speedup_vs_reference_marcher"] == pytest.approx(25.0)
    assert value["ours", "middle", "equal_quality_reference_ms"] == 20.0
    # Better than every marcher: a lower bound against the slowest, the reference.
    reference = eq.REFERENCE.label
    assert value["perfect", reference, "equal_quality_speedup"] == pytest.approx(50.0)
    assert set(rows[rows.model == "perfect"].bound) == {shared.LOWER}
    assert value[eq.RAY_MARCHER, "tie", "ms_per_frame"] == 30.0
    assert len(rows[rows.model == eq.RAY_MARCHER]) == 5 * 3


def test_network_targets_average_the_first_examples_only():
    frame = pd.DataFrame(
        {
            "example": [0, 0, 1, 1, 2, 0, 1],
            "model": ["ours"] * 5 + ["other"] * 2,
            "metric": ["iou_depth", "normal_error_mean_deg"] * 2 + ["iou_depth"] * 3,
            "value": [0.9, 8.0, 0.7, 6.0, 0.0, 0.5, 0.6],
        }
    )
    targets = eq.network_targets(frame, [0, 1])
    assert targets["ours"] == pytest.approx({"iou_depth": 0.8, "normal_error_mean_deg": 7.0})
    assert targets["other"] == pytest.approx({"iou_depth": 0.55})


def test_the_job_scores_every_network_and_setting_on_the_first_examples(tmp_path):
    from neurender import io
    from neurender.metaballs import REFINED_BASELINE, VARIANTS, jobs

    scene = {"seed": 1, "width": 32, "balls": [2, 4], "radius": [1, 2], **THESIS_SCENES}
    files = write_splits(tmp_path, scene, {"train": 2, "val": 1, "test": 2})
    checkpoints = train_variants(files, tmp_path, 32)
    test = {k: files[f"test_{k}"] for k in ("dir", "manifest", "balls")}
    inputs = {f"test_{k}": v for k, v in test.items()} | {"checkpoints": checkpoints}
    evaluated = {
        name: str(tmp_path / f"{name}.{ext}")
        for name, ext in (("metrics", "csv"), ("examples", "csv"), ("by_scene", "csv"))
    } | {"figure": str(tmp_path / "c.png"), "scene_figure": str(tmp_path / "s.png")}
    jobs.metaballs_evaluate(inputs, evaluated, {"width": 32, "device": "cpu", **KERNEL}, 1)
    shipped = {
        "onnx": [str(tmp_path / "onnx" / f"{v}.onnx") for v in VARIANTS],
        "table": str(tmp_path / "deployment.csv"),
    }
    jobs.metaballs_deploy(inputs, shipped, KERNEL, 1)
    inputs |= {"onnx": shipped["onnx"]}
    outputs = {"table": str(tmp_path / "eq.csv"), "figure": str(tmp_path / "eq.png")}
    params = {"equal_quality_examples": 1, "width": 32, "device": "cpu", **KERNEL}
    jobs.metaballs_equal_quality(inputs | {"examples": evaluated["examples"]}, outputs, params, 1)

    table = io.read_csv(outputs["table"])
    marchers = table[table.model == eq.RAY_MARCHER]
    assert set(marchers.setting) == {m.label for m in eq.sweep()}
    reference = marchers[marchers.setting == eq.REFERENCE.label].set_index("metric")["value"]
    assert reference["iou_depth"] > 0.99  # the targets' own marcher, through 8 bits
    per_example = io.read_csv(evaluated["examples"])
    first = per_example[per_example.example == per_example.example.min()]
    for variant in VARIANTS:
        rows = table[table.model == variant].set_index("metric")["value"]
        expected = first[first.model == variant].set_index("metric")["value"]
        for metric in eq.QUALITY:
            assert rows[metric] == pytest.approx(expected[metric])
        pick = table[table.model == variant].setting.iloc[0]
        ms = marchers[(marchers.setting == pick) & (marchers.metric == "ms_per_frame")]
        ratio = ms.value.iloc[0] / rows["ms_per_frame"]
        assert rows["equal_quality_speedup"] == pytest.approx(ratio)
    refined = table[table.model == REFINED_BASELINE].set_index("metric")["value"]
    expected = first[first.model == REFINED_BASELINE].set_index("metric")["value"]
    assert refined["iou_depth"] == pytest.approx(expected["iou_depth"])
    assert refined["ms_per_frame"] > 0  # the no-learning renderer timed beside the networks
    assert open(outputs["figure"], "rb").read(4) == b"\x89PNG"


def test_an_empty_frame_is_left_out_of_a_settings_quality_means():
    scene = _scenes(1)[0]
    empty = scenes.sample_scene(1, (1e-9, 1e-9), torch.Generator().manual_seed(1))
    examples = [
        (s, raymarch.render_gbuffers(s, 16).stack()) for s in (scene, empty.to(torch.float32))
    ]
    coarse = eq.March(min_step=1.0)
    both = eq.score_settings(examples, 16, [coarse]).iloc[0]
    alone = eq.score_settings(examples[:1], 16, [coarse]).iloc[0]
    assert both["iou_depth"] == alone["iou_depth"] < 1.0  # not raised by a perfect empty one
    only_empty = eq.score_settings(examples[1:], 16, [coarse]).iloc[0]
    assert math.isnan(only_empty["iou_depth"])
