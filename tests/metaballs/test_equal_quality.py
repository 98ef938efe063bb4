import math

import pandas as pd
import pytest
import torch

from neurender.metaballs import equal_quality as eq
from neurender.metaballs import raymarch, scenes


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
            assert eq.reaches(scores.loc[[finer]], target).all()


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


def test_the_pick_is_the_fastest_setting_reaching_both_targets(tmp_path):
    scores = _synthetic()
    target = {"iou_depth": 0.93, "normal_error_mean_deg": 7.8}  # "middle" meets it exactly
    assert eq.reaches(scores, target).tolist() == [True, False, True, True, True]
    assert eq.cheapest(scores, target)["label"] == "middle"
    assert eq.equal_quality_speedup(scores, target, 4.0) == pytest.approx(5.0)
    stricter = {"iou_depth": 0.94, "normal_error_mean_deg": 7.8}
    assert eq.cheapest(scores, stricter)["label"] == "tie"
    unreachable = {"iou_depth": 1.0, "normal_error_mean_deg": 0.1}
    assert eq.cheapest(scores, unreachable) is None
    assert math.isnan(eq.equal_quality_speedup(scores, unreachable, 4.0))
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
    assert value["ours", "middle", "equal_quality_marcher_ms"] == 20.0
    assert math.isnan(value["perfect", "none", "equal_quality_speedup"])
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
