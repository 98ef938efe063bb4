"""Your metaball scenes: the CSV checked with the file and lines named, scenes grouped, and
scored against the ray marcher like the test set."""

import math

import numpy as np
import pandas as pd
import pytest
import torch

from neurender.metaballs import method, raymarch
from neurender.metaballs.model import network_inputs
from neurender.metaballs.scene_file import read_user_scenes
from neurender.metaballs.user_scenes import outside_training, score_user_scenes, to_scenes

BALLS = pd.DataFrame(
    {
        "scene": ["a", "b", "a", "b"],
        "x": [-1.0, 0.0, 1.0, 0.5],
        "y": [0.0, 0.5, 0.2, -0.5],
        "z": [15.0, 12.0, 15.5, 12.5],
        "radius": [1.0, 0.8, 1.2, 0.9],
        "r": [0.9, 0.1, 0.2, 0.5],
        "g": [0.2, 0.8, 0.3, 0.5],
        "b": [0.1, 0.3, 0.9, 0.5],
        "note": ["", "", "ignored", ""],
    }
)


def _csv(tmp_path, frame, name="scenes.csv"):
    path = tmp_path / name
    frame.to_csv(path, index=False)
    return path


def test_scenes_group_by_id_in_order_of_first_appearance(tmp_path):
    balls = read_user_scenes(_csv(tmp_path, BALLS))
    scenes = to_scenes(balls)
    assert list(scenes) == ["a", "b"]
    a = scenes["a"]
    assert len(a) == 2 and a.centres.dtype == torch.float32
    np.testing.assert_allclose(a.centres.numpy(), [[-1, 0, 15], [1, 0.2, 15.5]])
    np.testing.assert_allclose(a.radii.numpy(), [1.0, 1.2])
    np.testing.assert_allclose(a.colours[1].numpy(), [0.2, 0.3, 0.9])


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda f: f.drop(columns="radius"), r"lacks columns \['radius'\]"),
        (
            lambda f: f.assign(z=["15", "x", "12", "13"]),
            r"column z is not a finite number on line\(s\) 3",
        ),
        (
            lambda f: f.assign(x=[0.0, math.inf, 0.0, 0.0]),
            r"column x is not a finite number on line\(s\) 3",
        ),
        (
            lambda f: f.assign(radius=[1.0, 0.0, -1.0, 1.0]),
            r"radius must be > 0; not so on line\(s\) 3, 4",
        ),
        (
            lambda f: f.assign(g=[0.5, 0.5, 1.5, 0.5]),
            r"r, g, b must lie in \[0, 1\]; not so on line\(s\) 4",
        ),
        (lambda f: f.assign(z=[15.0, -3.0, 15.0, 12.0]), r"z must be > 0 .*line\(s\) 3"),
        (lambda f: f.iloc[:0], r"has no rows"),
    ],
)
def test_bad_scenes_are_refused_naming_the_file_and_lines(tmp_path, change, message):
    path = _csv(tmp_path, change(BALLS.copy()), "bad.csv")
    with pytest.raises(ValueError, match=message) as err:
        read_user_scenes(path)
    assert "bad.csv" in str(err.value)


def test_the_config_check_refuses_a_bad_scenes_file_before_any_job(tmp_path):
    path = _csv(tmp_path, BALLS.assign(radius=[1.0, 0.0, 1.0, 1.0]), "bad.csv")
    cfg = {
        "metaballs": {"balls": [2, 6], "radius": [0.6, 1.6], "width": 32, "user_scenes": str(path)}
    }
    (problem,) = list(method.problems(cfg))
    assert (
        problem.startswith(f"metaballs.user_scenes = '{path}'") and "radius must be > 0" in problem
    )
    missing = {"metaballs": {**cfg["metaballs"], "user_scenes": str(tmp_path / "none.csv")}}
    assert "none.csv" in next(iter(method.problems(missing)))
    made = {"metaballs": {**cfg["metaballs"], "user_scenes": "results/examples/balls.csv"}}
    assert list(method.problems(made)) == []  # the workflow makes it; checked then


def test_balls_outside_the_training_range_are_reported_per_scene(tmp_path):
    far = BALLS.assign(z=[15.0, 30.0, 15.0, 12.0], x=[-1.0, 0.0, 9.0, 0.5])
    notes = outside_training(read_user_scenes(_csv(tmp_path, far)))
    assert notes == [
        "scene a: 0 ball(s) outside depths 7-25, 1 outside the field of view (the networks "
        "never saw such balls)",
        "scene b: 1 ball(s) outside depths 7-25, 0 outside the field of view (the networks "
        "never saw such balls)",
    ]
    assert outside_training(read_user_scenes(_csv(tmp_path, BALLS))) == []


class RayMarcher:
    """A stand-in renderer that is exact: the ray marcher itself."""

    def __init__(self, width):
        self.width = width

    def inputs(self, scene, circles=None):
        return network_inputs(scene, self.width, "pix2pix", circles)

    def __call__(self, x):
        return torch.stack([raymarch.render_gbuffers(self.scene, self.width).stack()])


def test_scores_are_the_test_sets_metrics_and_an_exact_renderer_scores_perfectly(tmp_path):
    scenes = to_scenes(read_user_scenes(_csv(tmp_path, BALLS)))
    exact = RayMarcher(32)
    rows, shown = [], {}
    for label, scene in scenes.items():
        exact.scene = scene
        frame, show = score_user_scenes({label: scene}, {"exact": exact}, 32)
        rows.append(frame)
        shown.update(show)
    frame = pd.concat(rows)
    assert set(frame.model) == {"exact", "isolated spheres", "inflated spheres"}
    assert set(frame.scene) == {"a", "b"} and set(frame.balls) == {2}
    assert (frame.dataset == "your scenes").all()
    exact_rows = frame[frame.model == "exact"].set_index(["scene", "metric"])["value"]
    for label in ("a", "b"):
        assert exact_rows[(label, "iou_depth")] == 1.0
        assert exact_rows[(label, "l1_normal")] < 1 / 255  # the truth went through 8 bits
        assert exact_rows[(label, "normal_error_mean_deg")] < 1.0
    assert shown["a"].circles.shape == (4, 32, 32) and shown["a"].truth.shape == (7, 32, 32)
