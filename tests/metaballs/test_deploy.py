"""The metaballs deployment job: each trained generator as an ONNX file that renders what
the renderer renders, one image at a time for the GAN-trained one."""

import numpy as np
import pandas as pd
import pytest
import torch
from PIL import Image

from neurender.deployment import COLUMNS, read_deployment, shipped_network
from neurender.metaballs import VARIANTS, jobs, scenes
from neurender.metaballs.renderer import MetaballRenderer
from neurender.nn.inference import OnnxNetwork
from neurender.nn.unet import count_parameters

from .keys import KERNEL, THESIS_SCENES
from .tiny import train_variants, write_splits

WIDTH = 32


@pytest.fixture(scope="module")
def deployed(tmp_path_factory):
    """The deploy job's outputs for every variant, each trained for one epoch."""
    tmp = tmp_path_factory.mktemp("metaballs_deploy")
    scene = {"seed": 1, "width": WIDTH, "balls": [2, 4], "radius": [1, 2], **THESIS_SCENES}
    files = write_splits(tmp, scene, {"train": 4, "val": 2, "test": 1})
    checkpoints = train_variants(files, tmp, WIDTH)
    inputs = {"test_balls": files["test_balls"], "checkpoints": checkpoints}
    outputs = {
        "onnx": [str(tmp / "onnx" / f"{v}.onnx") for v in VARIANTS],
        "table": str(tmp / "deployment.csv"),
    }
    jobs.metaballs_deploy(inputs, outputs, KERNEL, 1)
    return inputs, outputs


def test_one_row_per_variant_with_its_size_and_positive_times(deployed):
    inputs, outputs = deployed
    table = read_deployment(outputs["table"])
    assert list(table.columns) == list(COLUMNS)
    assert list(table.network) == list(VARIANTS) and set(table.method) == {"metaballs"}
    assert (table.resolution == f"{WIDTH}x{WIDTH}").all()
    for row, checkpoint, onnx_file in zip(
        table.itertuples(), inputs["checkpoints"], outputs["onnx"], strict=True
    ):
        assert row.parameters == count_parameters(MetaballRenderer(checkpoint, "cpu").model)
        assert row.onnx_file == onnx_file
        with open(onnx_file, "rb") as f:
            assert row.onnx_bytes == len(f.read())
        assert 0 <= row.max_abs_diff_vs_pytorch <= 1e-3
    assert (table.onnxruntime_ms_per_frame > 0).all() and (table.pytorch_ms_per_frame > 0).all()


@pytest.mark.parametrize("variant", VARIANTS)
def test_the_file_renders_what_the_renderer_renders_on_fresh_scenes(deployed, variant):
    inputs, outputs = deployed
    renderer = MetaballRenderer(inputs["checkpoints"][VARIANTS.index(variant)], "cpu")
    gen = torch.Generator().manual_seed(7)
    fresh = [scenes.sample_scene(n, (1.0, 2.0), gen).to(torch.float32) for n in (2, 4, 6)]
    x = torch.stack([renderer.inputs(scene) for scene in fresh])
    # Three different images in one batch: a GAN-trained generator's graph must normalise
    # each with its own statistics, as the renderer does one image at a time.
    expected = renderer(x).numpy()
    got = OnnxNetwork(outputs["onnx"][VARIANTS.index(variant)])(x.numpy())
    np.testing.assert_allclose(got, expected, atol=1e-4)
    assert not np.allclose(got[0], got[1], atol=1e-3)  # the images differ


def test_a_cpu_renderer_given_its_shipped_graph_runs_that_graph_and_no_other(deployed):
    inputs, outputs = deployed
    gen = torch.Generator().manual_seed(3)
    scene = scenes.sample_scene(4, (1.0, 2.0), gen).to(torch.float32)
    for i, checkpoint in enumerate(inputs["checkpoints"]):
        in_torch = MetaballRenderer(checkpoint, "cpu")
        shipped = MetaballRenderer(checkpoint, "cpu", onnx=outputs["onnx"][i])
        assert (in_torch.engine, shipped.engine) == ("pytorch", "onnxruntime")
        x = shipped.inputs(scene)[None]
        np.testing.assert_allclose(shipped(x).numpy(), in_torch(x).numpy(), atol=1e-4)
    # each graph names its variant, and a checkpoint refuses another variant's graph
    assert [shipped_network(f) for f in outputs["onnx"]] == [("metaballs", v) for v in VARIANTS]
    with pytest.raises(ValueError) as refused:
        MetaballRenderer(inputs["checkpoints"][0], "cpu", onnx=outputs["onnx"][1])
    for named in (outputs["onnx"][1], inputs["checkpoints"][0], VARIANTS[0], VARIANTS[1]):
        assert str(named) in str(refused.value)


def test_the_demo_times_every_network_against_ray_marching_and_draws_its_figures(
    deployed, tmp_path
):
    inputs, outputs = deployed
    params = {"seed": 1, "device": "cpu", "width": WIDTH, "radius": [1, 2], **KERNEL}
    params |= {"demo_frames": 2, "demo_balls": 3, "timing_balls": [2, 5]}
    files = {name: str(tmp_path / f"{name}.csv") for name in ("frames", "timing", "balls")} | {
        name: str(tmp_path / f"{name}.png") for name in ("balls_png", "strip", "stability")
    }
    files["gif"] = str(tmp_path / "demo.gif")
    jobs.metaballs_demo(
        {"checkpoints": inputs["checkpoints"], "onnx": outputs["onnx"]}, files, params, 1
    )
    balls = pd.read_csv(files["balls"])
    assert sorted(set(balls.balls)) == [2, 5]  # every count timed
    assert (balls.ms_per_frame > 0).all()
    timing = pd.read_csv(files["timing"])
    assert set(VARIANTS) <= set(timing.model)
    frames = pd.read_csv(files["frames"])
    assert frames.frame.nunique() == 2
    gif = Image.open(files["gif"])
    assert gif.n_frames == 2
    for png in ("balls_png", "strip", "stability"):
        assert np.asarray(Image.open(files[png]).convert("RGB")).std() > 1
