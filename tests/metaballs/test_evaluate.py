import math

import pandas as pd
import pytest
import torch

from neurender.metaballs import EMPTY_FRAME, EMPTY_FRAMES, evaluate, gbuffers, inputs, raymarch


def test_blended_balls_differ_from_isolated_spheres(make_scene):
    scene = make_scene([[0.0, 0.0, 14.0], [1.6, 0.0, 14.0]], [1.2, 1.2])
    a = inputs.draw_spheres(scene, 48).stack()
    b = raymarch.render_gbuffers(scene, 48).stack()
    m = evaluate.example_metrics(a, b)
    assert m["iou_depth"] < 0.98 and m["normal_error_mean_deg"] > 1.0  # blending is missing


def test_perfect_prediction_scores_perfectly(make_scene):
    scene = make_scene([[0.0, 0.0, 12.0], [1.0, 1.0, 16.0]], [1.0, 1.5])
    g = raymarch.render_gbuffers(scene, 32).stack()
    m = evaluate.example_metrics(g, g)
    assert m["iou_depth"] == 1.0 and m["iou_normal"] == 1.0
    assert m["l1_colour"] == 0.0 and m["l1_depth"] == 0.0 and m["l1_normal"] == 0.0
    assert m["depth_error_world"] == 0.0
    assert m["normal_error_mean_deg"] == pytest.approx(0.0, abs=0.05)
    for buffer in ("colour", "depth", "normal"):
        assert m[f"ssim_{buffer}"] == pytest.approx(1.0, abs=1e-4)


def test_depth_error_is_in_world_units(make_scene):
    scene = make_scene([[0.0, 0.0, 12.0]], [2.0])
    g = raymarch.render_gbuffers(scene, 32).stack()
    shifted = g.clone()
    shifted[3] += 0.01  # 0.01 of the 18-unit depth range
    assert evaluate.example_metrics(shifted, g)["depth_error_world"] == pytest.approx(
        0.18, rel=1e-4
    )


def test_iou():
    a = torch.tensor([True, True, False, False])
    b = torch.tensor([True, False, True, False])
    assert evaluate.iou(a, b) == pytest.approx(1 / 3)
    assert math.isnan(evaluate.iou(a & False, b & False))  # both empty: no overlap to score


def test_binned_means():
    frame = pd.DataFrame(
        {
            "model": ["a"] * 4,
            "balls": [1, 2, 8, 9],
            "metric": ["x"] * 4,
            "value": [1.0, 3.0, 5.0, 7.0],
        }
    )
    out = evaluate.binned(frame, "balls", [0, 5, 10])
    assert out.value.tolist() == [2.0, 6.0]


def test_accuracy_by_scene_bins_by_balls_and_by_overlap_gap():
    frame = pd.DataFrame(
        {
            "model": ["a"] * 4,
            "balls": [3, 4, 12, 30],
            "min_depth_separation": [0.2, float("nan"), 3.0, 3.5],
            "metric": ["x"] * 4,
            "value": [1.0, 3.0, 5.0, 7.0],
        }
    )
    out = evaluate.accuracy_by_scene(frame)
    by_balls = out[out.by == "balls"]
    assert by_balls.value.tolist() == [2.0, 5.0, 7.0]  # the last bin grows to 30 balls
    by_gap = out[out.by == "min_depth_separation"]
    assert by_gap.value.tolist() == [1.0, 6.0]  # the example without overlaps left out


def test_an_empty_reference_is_not_scored_as_perfect_but_marked_empty(make_scene):
    # A ball of radius 1e-9: nothing of the surface reaches a pixel.
    empty = raymarch.render_gbuffers(make_scene([[0.0, 0.0, 15.0]], [1e-9]), 32).stack()
    assert not gbuffers.silhouette_depth(empty).any()
    assert evaluate.example_metrics(empty, empty) == {EMPTY_FRAME: 1.0}
    drawn = inputs.draw_spheres(make_scene([[0.0, 0.0, 15.0]], [2.0]), 32).stack()
    assert evaluate.example_metrics(drawn, empty) == {EMPTY_FRAME: 1.0}  # nothing to score


def test_a_frame_with_a_surface_keeps_every_score_and_is_marked_not_empty(make_scene):
    scene = make_scene([[0.0, 0.0, 12.0], [1.0, 1.0, 16.0]], [1.0, 1.5])
    g = raymarch.render_gbuffers(scene, 32).stack()
    m = evaluate.example_metrics(inputs.draw_spheres(scene, 32).stack(), g)
    assert m[EMPTY_FRAME] == 0.0 and list(m)[-1] == EMPTY_FRAME  # after the scores
    assert {"iou_depth", "iou_normal", "depth_error_world", "normal_error_mean_deg"} <= set(m)
    assert all(math.isfinite(v) for v in m.values())


def test_means_leave_empty_frames_out_and_count_them_per_model():
    keys = {"method": "metaballs", "dataset": "test scenes", "split": "test"}
    rows = [
        # model a: two scored frames and one empty; model b: one scored frame
        *[
            {**keys, "model": "a", "example": 0, "metric": m, "value": v}
            for m, v in [("iou_depth", 0.5), (EMPTY_FRAME, 0.0)]
        ],
        *[
            {**keys, "model": "a", "example": 1, "metric": m, "value": v}
            for m, v in [("iou_depth", 0.7), (EMPTY_FRAME, 0.0)]
        ],
        {**keys, "model": "a", "example": 2, "metric": EMPTY_FRAME, "value": 1.0},
        *[
            {**keys, "model": "b", "example": 0, "metric": m, "value": v}
            for m, v in [("iou_depth", 0.9), (EMPTY_FRAME, 0.0)]
        ],
    ]
    means = evaluate.mean_metrics(pd.DataFrame(rows)).set_index(["model", "metric"])["value"]
    assert means[("a", "iou_depth")] == pytest.approx(0.6)  # not (0.5 + 0.7 + 1) / 3
    assert means[("a", EMPTY_FRAMES)] == 1.0 and means[("b", EMPTY_FRAMES)] == 0.0
    assert EMPTY_FRAME not in means.index.get_level_values("metric")
