"""Your metaball scenes: the CSV checked with the file and lines named, scenes grouped, and
scored against the ray marcher like the test set."""

import math

import numpy as np
import pandas as pd
import pytest
import torch

from neurender.metaball import THRESHOLD
from neurender.metaballs import (
    EMPTY_FRAME,
    VARIANTS,
    gbuffers,
    jobs,
    method,
    raymarch,
    renderer,
    scene_file,
)
from neurender.metaballs.model import network_inputs
from neurender.metaballs.scene_file import read_user_scenes
from neurender.metaballs.user_scenes import (
    NEAR_PLANE_CUT,
    near_plane_cut,
    outside_training,
    score_user_scenes,
    to_scenes,
    view_notes,
)

from .keys import KERNEL

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

#: The rest of the config the check reads: no structure files of yours.
NO_STRUCTURES = {"metaballs_scale": {"user_structures": []}}


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
        **NO_STRUCTURES,
        "metaballs": {"balls": [2, 6], "radius": [0.6, 1.6], "width": 32, "user_scenes": str(path)},
    }
    (problem,) = list(method.problems(cfg))
    assert (
        problem.startswith(f"metaballs.user_scenes = '{path}'") and "radius must be > 0" in problem
    )
    missing = {**cfg, "metaballs": {**cfg["metaballs"], "user_scenes": str(tmp_path / "none.csv")}}
    assert "none.csv" in next(iter(method.problems(missing)))
    made = {**cfg, "metaballs": {**cfg["metaballs"], "user_scenes": "results/examples/balls.csv"}}
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
    assert set(frame.model) == {"exact", "isolated spheres", "inflated spheres", "refined spheres"}
    assert set(frame.scene) == {"a", "b"} and set(frame.balls) == {2}
    assert (frame.dataset == "your scenes").all()
    exact_rows = frame[frame.model == "exact"].set_index(["scene", "metric"])["value"]
    for label in ("a", "b"):
        assert exact_rows[(label, "iou_depth")] == 1.0
        assert exact_rows[(label, "l1_normal")] < 1 / 255  # the truth went through 8 bits
        assert exact_rows[(label, "normal_error_mean_deg")] < 1.0
        assert exact_rows[(label, EMPTY_FRAME)] == 0.0 and exact_rows[(label, NEAR_PLANE_CUT)] == 0
    assert view_notes(frame) == []  # an ordinary scene: nothing to warn about
    assert shown["a"].circles.shape == (4, 32, 32) and shown["a"].truth.shape == (7, 32, 32)


def _spreadsheet_csv(tmp_path, labels, name="typed.csv"):
    """The scenes as a spreadsheet exports them: labels as typed, pandas writing the CSV
    (a blank label is an empty cell)."""
    rows = [
        {"scene": s, "x": 0.2 * i, "y": 0.0, "z": 15.0, "radius": 1.0, "r": 0.5, "g": 0.5, "b": 0.5}
        for i, s in enumerate(labels)
    ]
    return _csv(tmp_path, pd.DataFrame(rows), name)


@pytest.mark.parametrize(
    "labels",
    [
        ["001", "1", "1.0", "1"],  # three scenes, not one number
        ["NA", "None", "null", "nan", "N/A", "NaN"],  # labels, not missing values
        ["a", " a", "$x$"],
    ],
)
def test_scene_labels_are_text_exactly_as_typed(tmp_path, labels):
    balls = read_user_scenes(_spreadsheet_csv(tmp_path, labels))
    assert balls["scene"].tolist() == labels
    scenes = to_scenes(balls)
    assert list(scenes) == list(dict.fromkeys(labels))
    assert sum(len(s) for s in scenes.values()) == len(labels)  # no ball dropped


def test_a_ball_without_a_label_is_refused_naming_the_file_and_line(tmp_path):
    path = _spreadsheet_csv(tmp_path, ["a", "a", "", "b", "  "], "blank.csv")
    with pytest.raises(ValueError) as err:
        read_user_scenes(path)
    assert str(err.value) == (
        f"metaball scenes {path}: a ball without a scene label on line(s) 4, 6 (the header "
        "is line 1); give every row its scene's label"
    )


def test_a_trailing_delimiter_does_not_shift_columns_and_an_extra_value_is_refused(tmp_path):
    # A trailing delimiter on every row once made pandas take the labels as an index.
    path = tmp_path / "trailing.csv"
    path.write_text("scene,x,y,z,radius,r,g,b\na,0,0,15,1,0.5,0.6,0.7,\nb,1,0,15,1,0.5,0.6,0.7,\n")
    balls = read_user_scenes(path)
    assert balls["scene"].tolist() == ["a", "b"] and balls["x"].tolist() == [0.0, 1.0]
    assert balls["b"].tolist() == [0.7, 0.7]
    extra = tmp_path / "extra.csv"
    extra.write_text("scene,x,y,z,radius,r,g,b\na,0,0,15,1,0.5,0.6,0.7,9\n")
    with pytest.raises(OSError, match=f"cannot parse CSV file {extra}: a row has more cells"):
        read_user_scenes(extra)


def test_a_folder_or_fifo_given_as_the_scenes_file_is_named_as_such(tmp_path):
    import os

    folder = tmp_path / "scenes.csv"
    folder.mkdir()
    with pytest.raises(FileNotFoundError, match=f"CSV file {folder} is a folder"):
        read_user_scenes(folder)
    fifo = tmp_path / "pipe.csv"
    os.mkfifo(fifo)
    with pytest.raises(FileNotFoundError, match=rf"CSV file {fifo} is a named pipe \(FIFO\)"):
        read_user_scenes(fifo)
    cfg = {"metaballs": {"balls": [2, 6], "radius": [0.6, 1.6], "width": 32}}
    scenes = {**cfg["metaballs"], "user_scenes": str(fifo)}
    (problem,) = method.problems({**NO_STRUCTURES, "metaballs": scenes})
    assert problem == (
        f"metaballs.user_scenes = '{fifo}': CSV file {fifo} is a named pipe (FIFO), not a file"
    )


def test_the_scenes_figure_draws_labels_as_plain_text(tmp_path, monkeypatch):
    from neurender.metaballs import figures
    from neurender.metaballs.evaluate import Showcase

    drawn = {}

    def keep(fig, path):
        fig.canvas.draw()  # math text is parsed here: "$\\frac$" would raise
        drawn["titles"] = [ax.title for ax in fig.axes]

    monkeypatch.setattr(figures, "save_figure", keep)
    stack = torch.zeros(7, 8, 8)
    stack[4:7, 2:6, 2:6] = 1.0
    labels = ["$x$", "$\\frac$", "a_b^c"]  # "$\\frac$" does not parse as math
    shown = {s: Showcase(2, torch.zeros(4, 8, 8), stack, {"pix2pix": stack}) for s in labels}
    figures.user_scenes_figure(shown, ["pix2pix"], str(tmp_path / "your_scenes.png"))
    titles = [t for t in drawn["titles"] if "circles" in t.get_text()]
    assert [t.get_text() for t in titles] == [f"scene {s} (2 balls): circles" for s in labels]
    assert not any(t.get_parse_math() or t.get_usetex() for t in drawn["titles"])


def _one_ball(tmp_path, name, z, radius, scene="tiny", x=0.0):
    """The scenes :data:`BALLS` with a last row (line 6) of one ball in a scene of its own."""
    row = {"scene": scene, "x": x, "y": 0.0, "z": z, "radius": radius}
    row |= {"r": 0.5, "g": 0.5, "b": 0.5, "note": ""}
    return _csv(tmp_path, pd.concat([BALLS, pd.DataFrame([row])], ignore_index=True), name)


class Blank:
    """A stand-in network that draws nothing (background everywhere)."""

    def __init__(self, width):
        self.width = width

    def inputs(self, scene, circles=None):
        return network_inputs(scene, self.width, "pix2pix", circles)

    def __call__(self, x):
        out = torch.zeros(len(x), 7, self.width, self.width)
        out[:, gbuffers.DEPTH] = 1.0
        return out


def test_a_scene_with_nothing_in_view_is_warned_marked_empty_and_not_scored_as_perfect(
    tmp_path, monkeypatch, caplog
):
    path = _one_ball(tmp_path, "tiny.csv", 15.0, 1e-9)
    monkeypatch.setattr(renderer, "load_renderers", lambda *a: {v: Blank(32) for v in VARIANTS})
    outputs = {"table": str(tmp_path / "user_scenes.csv"), "figure": str(tmp_path / "f.png")}
    params = {"device": "cpu", "width": 32, **KERNEL}
    with caplog.at_level("WARNING"):
        jobs.metaballs_user_scenes({"scenes": str(path), "checkpoints": []}, outputs, params, 1)
    # The table the report reads: the empty scene has its mark and no score, for every model
    # (a blank network's empty frame would otherwise score IoU 1 and SSIM 1).
    table = pd.read_csv(outputs["table"])
    tiny = table[table.scene == "tiny"]
    assert set(tiny.model) == {*VARIANTS, "isolated spheres", "inflated spheres", "refined spheres"}
    assert set(tiny.metric) == {EMPTY_FRAME, NEAR_PLANE_CUT}
    assert (tiny[tiny.metric == EMPTY_FRAME].value == 1.0).all()
    others = table[table.scene != "tiny"]
    assert (others[others.metric == EMPTY_FRAME].value == 0.0).all()
    assert "iou_depth" in set(others.metric)
    (warning,) = [r.getMessage() for r in caplog.records if "nothing of the surface" in r.message]
    assert str(path) in warning and "scene 'tiny'" in warning and "empty_frame = 1" in warning


def test_a_ball_holding_the_camera_is_refused_naming_the_file_scene_and_line(tmp_path):
    path = _one_ball(tmp_path, "wall.csv", 15.0, 1e3, scene="wall")
    with pytest.raises(ValueError) as err:
        read_user_scenes(path)
    message = str(err.value)
    assert message.startswith(f"metaball scenes {path}: scene 'wall': the camera")
    assert "inside the metaball surface" in message and "line(s) 6" in message
    assert "radius 1000 at distance 15" in message and "Expected a field below 1" in message
    assert scene_file.SURFACE_FIELD == THRESHOLD  # the torch-free copy of the surface level
    cfg = {"balls": [2, 6], "radius": [0.6, 1.6], "width": 32, "user_scenes": str(path)}
    (problem,) = method.problems({**NO_STRUCTURES, "metaballs": cfg})  # refused before any job
    assert problem.startswith(f"metaballs.user_scenes = '{path}'") and "scene 'wall'" in problem


def test_balls_that_together_hold_the_camera_are_refused_naming_all_their_lines(tmp_path):
    # Each ball alone leaves the camera outside (r^2 / d^2 = 0.36), three of them do not.
    rows = [
        {"scene": "crowd", "x": x, "y": 0.0, "z": 4.0, "radius": 3.0, "r": 0, "g": 0, "b": 0}
        for x in (-3.0, 0.0, 3.0)
    ]
    rows[1]["z"] = 5.0
    path = _csv(tmp_path, pd.concat([BALLS, pd.DataFrame(rows)], ignore_index=True), "crowd.csv")
    with pytest.raises(ValueError, match=r"scene 'crowd'.*together.*line\(s\) 6, 7, 8"):
        read_user_scenes(path)


def test_the_near_plane_cut_is_where_the_marched_target_is_a_flat_wall(tmp_path, caplog):
    # A ball at depth 8.5 of radius 2.5 reaches depth 6, in front of the near plane at 7.
    path = _one_ball(tmp_path, "near.csv", 8.5, 2.5, scene="near")
    scene = to_scenes(read_user_scenes(path))["near"]
    marched = raymarch.render_gbuffers(scene, 32)
    wall = (marched.depth == 0).double().mean()  # the marcher stops at once: depth 7
    assert near_plane_cut(scene, 32) == pytest.approx(float(wall)) and 0.05 < wall < 1
    frame, _ = score_user_scenes({"near": scene}, {}, 32)
    cut = frame[frame.metric == NEAR_PLANE_CUT]
    assert set(cut.model) == {"isolated spheres", "inflated spheres", "refined spheres"}
    assert (cut.value == near_plane_cut(scene, 32)).all()
    (note,) = view_notes(frame)
    assert note.startswith("scene 'near': the near plane (depth 7) cuts the surface on")
    assert f"{NEAR_PLANE_CUT} = " in note
