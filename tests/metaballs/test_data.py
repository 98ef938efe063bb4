import math

import numpy as np
import pandas as pd
import torch

from neurender import io
from neurender.metaball import Scene
from neurender.metaballs import ab, data

from .keys import THESIS_SCENES

CFG = {"seed": 3, "width": 16, "balls": [2, 5], "radius": [1.0, 2.0], **THESIS_SCENES}


def test_generate_split_is_the_same_for_any_number_of_workers(tmp_path):
    runs = {w: data.generate_split(CFG, "test", 5, w, tmp_path / str(w)) for w in (1, 2)}
    (m1, b1), (m2, b2) = runs[1], runs[2]
    assert m1.example.tolist() == list(range(5)) and m1.balls.between(2, 5).all()
    pd.testing.assert_frame_equal(m1.drop(columns="seconds"), m2.drop(columns="seconds"))
    pd.testing.assert_frame_equal(b1, b2)
    for f in m1.file:
        np.testing.assert_array_equal(
            io.read_png(tmp_path / "1" / f), io.read_png(tmp_path / "2" / f)
        )
    assert ab.read_ab(tmp_path / "1" / m1.file[0])["inputs"].shape == (4, 16, 16)


def test_ball_table_gives_back_the_exact_scenes(tmp_path):
    manifest, balls = data.generate_split(CFG, "test", 4, 1, tmp_path / "test")
    io.write_csv(tmp_path / "balls.csv", balls)
    back = data.read_scenes(tmp_path / "balls.csv")
    assert sorted(back) == list(range(4))
    for i, scene in back.items():
        ref = data.example_scene(CFG, "test", i)
        assert len(scene) == manifest.balls[i]
        for a, b in ((scene.centres, ref.centres), (scene.radii, ref.radii)):
            assert torch.equal(a, b)
        assert torch.equal(scene.colours, ref.colours)


def _scene(centres, radii):
    c = torch.tensor(centres, dtype=torch.float32)
    return Scene(c, torch.tensor(radii, dtype=torch.float32), torch.zeros(len(c), 3))


def test_min_overlap_depth_gap_only_counts_overlapping_circles():
    apart = _scene([[-3.0, 0.0, 10.0], [3.0, 0.0, 12.0]], [0.5, 0.5])
    assert math.isnan(data.min_overlap_depth_gap(apart, 64))
    # three balls on the optical axis: every pair overlaps, the closest pair is 1.5 apart
    stacked = _scene([[0.0, 0.0, 10.0], [0.0, 0.0, 11.5], [0.0, 0.0, 14.0]], [1.0, 1.0, 1.0])
    assert data.min_overlap_depth_gap(stacked, 64) == 1.5
