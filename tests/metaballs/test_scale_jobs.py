"""The scale and real-scene jobs end to end on tiny networks trained on cluster scenes."""

import pandas as pd
import pytest
from PIL import Image

from neurender import io
from neurender.metaballs import VARIANTS, inputs, jobs, molecules, scale

from .tiny import train_variants, write_splits

WIDTH = 32
KERNEL = {"kernel": {"name": "wyvill", "support": 2.0, "sharpness": 1.0}}


@pytest.fixture(autouse=True)
def few_baselines(monkeypatch):
    """Two cheap no-learning renderers (each has its own tests): the jobs' work is what is
    tested here."""
    cheap = [
        scale.Setting("isolated spheres", "spheres", inputs.draw_spheres),
        scale.Setting("half-width marcher", "0.5 width", scale._marcher(0.5, 4)),
    ]
    monkeypatch.setattr(scale, "baselines", lambda: cheap)


@pytest.fixture(scope="module")
def shipped(tmp_path_factory):
    """``checkpoints`` and ``onnx`` of every variant trained a step on cluster scenes."""
    root = tmp_path_factory.mktemp("scale")
    scene = {"seed": 1, "width": WIDTH, "balls": [20, 200], "family": "cluster"}
    scene |= {"packing": 0.15, **KERNEL}
    files = write_splits(root, scene, {"train": 2, "val": 1, "test": 2})
    checkpoints = train_variants(files, root, WIDTH)
    onnx = [str(root / "onnx" / f"{v}.onnx") for v in VARIANTS]
    inputs = {"test_balls": files["test_balls"], "checkpoints": checkpoints}
    jobs.metaballs_deploy(inputs, {"onnx": onnx, "table": str(root / "d.csv")}, KERNEL, 1)
    return {"checkpoints": checkpoints, "onnx": onnx}


def test_the_scale_job_measures_every_renderer_at_every_count_and_width(shipped, tmp_path):
    outputs = {
        "rows": str(tmp_path / "scale.csv"),
        "equal_quality": str(tmp_path / "eq.csv"),
        "figure": str(tmp_path / "scale.png"),
    }
    scale_cfg = {"balls": [30, 300], "widths": [WIDTH, 2 * WIDTH], "scenes": 1, "repeats": 1}
    params = {"seed": 0, "device": "cpu", "width": WIDTH, "packing": 0.15, **KERNEL}
    jobs.metaballs_scale(shipped, outputs, params | {"scale": scale_cfg}, 1)

    rows = io.read_csv(outputs["rows"])
    renderers = {(s.renderer, s.setting) for s in scale.baselines()} | {(scale.EXACT, "reference")}
    for (_, width), part in rows.groupby(["balls", "width"]):
        assert renderers <= set(zip(part.renderer, part.setting, strict=True))
        nets = part[part.renderer.isin(VARIANTS)]
        assert set(nets.renderer) == set(VARIANTS)
        scored = "iou_depth" in set(nets.metric)
        assert scored == (width == WIDTH)  # trained width scored, the other timed only
        stats = part[part.renderer == scale.EXACT].set_index("metric")["value"]
        assert stats["near_plane"] == 0 and 0 < stats["covered"] < 1
    equal = io.read_csv(outputs["equal_quality"])
    assert len(equal) == len(VARIANTS) * 2 * 2 * len({r for r, _ in renderers})
    exact = equal[equal.renderer == scale.EXACT]
    # The exact renderer reaches any network's quality with its one setting: the fastest
    # of its sweep, so an upper bound (a cheaper exact render might reach it too).
    assert set(exact.bound) == {"upper bound"}
    assert (equal.speedup > 0).all()
    assert Image.open(outputs["figure"]).size[0] > 0


def test_the_real_scenes_job_scores_every_scene_and_animates_the_trajectory(shipped, tmp_path):
    outputs = {
        "table": str(tmp_path / "real.csv"),
        "figure": str(tmp_path / "real.png"),
        "trajectory": str(tmp_path / "trajectory.gif"),
    }
    cfg = {"structures": ["1a28", "adk_dims"], "ball_scale": 1.0, "trajectory_frames": 2}
    params = {"device": "cpu", "width": WIDTH, **KERNEL, "scale": cfg | {"repeats": 1}}
    # A user's structure file: the shipped 1a28 under another name.
    mine = tmp_path / "mine.pdb.gz"
    mine.write_bytes((molecules.STRUCTURES / "1a28.pdb.gz").read_bytes())
    jobs.metaballs_real_scenes(shipped | {"user_structures": [str(mine)]}, outputs, params, 1)

    table = io.read_csv(outputs["table"])
    assert set(table.scene) == {"1a28", "adk_dims frame 0", "adk_dims frame 11", "mine.pdb.gz"}
    atoms = table.groupby("scene").balls.first()
    assert atoms["1a28"] == len(molecules.read_structure(molecules.STRUCTURES / "1a28.pdb.gz"))
    assert atoms["mine.pdb.gz"] == atoms["1a28"]
    exact = table[table.renderer == scale.EXACT].pivot(index="scene", columns="metric")["value"]
    assert (exact.near_plane == 0).all() and (exact.covered > 0.05).all()
    # Your file is the same scene as the shipped entry: every score equal.
    by_scene = table.set_index(["renderer", "setting", "metric", "scene"])["value"].unstack()
    timings = [m for m in by_scene.index if m[2].startswith("ms_") or m[2] == "peak_mb"]
    scores = by_scene.drop(index=timings)
    pd.testing.assert_series_equal(scores["mine.pdb.gz"], scores["1a28"], check_names=False)
    nets = table[table.renderer.isin(VARIANTS) & (table.metric == "iou_depth")]
    assert len(nets) == 4 * len(VARIANTS)
    gif = Image.open(outputs["trajectory"])
    assert gif.n_frames == molecules.model_count(molecules.STRUCTURES / molecules.TRAJECTORY)
    assert gif.size == (2 * WIDTH, WIDTH)
