"""The NDR deployment job: each trained variant as an ONNX file that computes its network,
and NDR as the shipped graph that computes its coarse shading and network, in float32 and
in int8."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import torch

from neurender import io
from neurender.camera import pixel_rays
from neurender.deployment import COLUMNS, read_deployment
from neurender.ndr import data, deploy, graph_scores, jobs
from neurender.ndr.buffers import (
    BUFFERS,
    NOISY,
    NDRDataset,
    channels,
    light_features,
    lighting_rows,
)
from neurender.ndr.deploy import NDRGraph, graph_inputs
from neurender.ndr.model import load_model
from neurender.ndr.render import camera
from neurender.ndr.shipped import INPUTS as SHIPPED_INPUTS
from neurender.nn.inference import OnnxNetwork, onnx_metadata
from neurender.nn.unet import count_parameters

from .test_equal_quality import CFG

WIDTH = 32
#: A complex-data variant, the pix2pix baseline and a diffuse-data one.
DEPLOYED = ("ndr", "pix2pix", "real_shading")
#: The shipped graph's keys: the tiny complex-data config's scene keys at this width.
SHIPPED_CFG = {
    k: CFG[k]
    for k in (
        "seed",
        "primitives",
        "edge_length",
        "environment_height",
        "user_probes_dir",
        "user_probe_fraction",
        "small_sun_fraction",
        "coarse_height",
        "camera_distance",
        "fov",
    )
} | {"width": WIDTH}


def _write_split(folder, split: str, count: int, seed: int) -> dict[str, str]:
    """A split of random buffers in the file format of :mod:`neurender.ndr.buffers`."""
    rng = np.random.default_rng(seed)
    samples, manifest, lighting = folder / split, [], []
    for i in range(count):
        out = {}
        for group, suffixes in {**BUFFERS, **NOISY}.items():
            shape = (WIDTH, WIDTH, len(suffixes)) if suffixes else (WIDTH, WIDTH)
            values = rng.random(shape, dtype=np.float32)
            if group == "N":
                values = values * 2 - 1
                values /= np.linalg.norm(values, axis=-1, keepdims=True)
            elif group == "mask":
                values = (values > 0.2).astype(np.float32)
            elif group.startswith(("S_", "I_")):
                values = 4 * values  # HDR
            out.update(channels(group, values))
        io.write_exr(samples / f"{i:05d}.exr", out)
        manifest.append({"sample": i, "file": f"{i:05d}.exr"})
        lighting += lighting_rows(i, rng.normal(size=75).astype(np.float32))
    files = {
        "dir": str(samples),
        "manifest": str(folder / f"{split}_manifest.csv"),
        "lighting": str(folder / f"{split}_lighting.csv"),
    }
    io.write_csv(files["manifest"], pd.DataFrame(manifest))
    io.write_csv(files["lighting"], pd.DataFrame(lighting))
    return files


def _split_inputs(prefix: str, files: dict[str, str]) -> dict[str, str]:
    return {f"{prefix}_{key}": path for key, path in files.items()}


@pytest.fixture(scope="module")
def deployed(tmp_path_factory):
    """The deploy job's outputs for :data:`DEPLOYED`, each trained for one epoch, and a
    fresh test split that neither training nor the export's check saw."""
    tmp = tmp_path_factory.mktemp("ndr_deploy")
    inputs = {}
    for prefix in ("", "diffuse_"):
        train = _write_split(tmp, f"{prefix}train", 4, 1)
        val = _write_split(tmp, f"{prefix}val", 2, 2)
        if not prefix:  # the int8 shipped graph's calibration
            inputs |= _split_inputs("train", train)
        inputs |= _split_inputs(f"{prefix}test", _write_split(tmp, f"{prefix}test", 1, 3))
        for variant in DEPLOYED:
            if (variant == "real_shading") != (prefix == "diffuse_"):
                continue
            params = {"seed": 0, "device": "cpu", "variant": variant, "mask_erosion": 1}
            params |= {"epochs": 1, "batch_size": 2, "lr": 1e-3, "lr_schedule": "constant"}
            params |= {"widths": [4, 8], "sh_hidden": 8, "shading_residual": True}
            params |= {"ngf": 4, "ndf": 4, "width": WIDTH, "l1_weight": 100.0, "gan_weight": 1.0}
            checkpoint = str(tmp / f"{variant}.pt")
            train_files = _split_inputs("train", train) | _split_inputs("val", val)
            outputs = {"checkpoint": checkpoint, "loss": str(tmp / f"{variant}_loss.csv")}
            outputs["tensorboard"] = str(tmp / "tensorboard" / variant / "run.json")
            jobs.ndr_train(train_files, outputs, params, 1)
            inputs[f"checkpoint_{variant}"] = checkpoint
    outputs = {
        "onnx": [str(tmp / "onnx" / f"{v}.onnx") for v in DEPLOYED],
        "table": str(tmp / "deployment.csv"),
        "shipped": str(tmp / "onnx" / "ndr_shipped.onnx"),
        "shipped_int8": str(tmp / "onnx" / "ndr_shipped_int8.onnx"),
    }
    jobs.ndr_deploy(inputs, outputs, SHIPPED_CFG | {"variants": list(DEPLOYED)}, 1)
    fresh = NDRDataset.from_files(_write_split(tmp, "fresh", 3, 4), 0)
    return inputs, outputs, fresh


def test_every_variant_logs_its_curves_and_previews(deployed, tensorboard_steps):
    inputs, _, _ = deployed
    for variant in DEPLOYED:
        folder = Path(inputs[f"checkpoint_{variant}"]).parent / "tensorboard" / variant
        logged = tensorboard_steps(folder)
        assert logged["val/loss"] == logged["previews/dssim"] == [1], variant
        assert logged["previews/prediction"] == logged["previews/reference"] == [1], variant


def test_one_row_per_variant_with_its_file_size_and_positive_times(deployed):
    inputs, outputs, _ = deployed
    table = read_deployment(outputs["table"])
    assert list(table.columns) == list(COLUMNS)
    assert list(table.network) == list(DEPLOYED) and set(table.method) == {"ndr"}
    assert (table.resolution == f"{WIDTH}x{WIDTH}").all()
    for row, onnx_file in zip(table.itertuples(), outputs["onnx"], strict=True):
        model = load_model(inputs[f"checkpoint_{row.network}"], torch.device("cpu"))
        assert row.parameters == count_parameters(model)
        assert row.onnx_file == onnx_file
        with open(onnx_file, "rb") as f:
            assert row.onnx_bytes == len(f.read())
        stored = float(onnx_metadata(onnx_file)["neurender.max_abs_diff_vs_pytorch"])
        assert row.max_abs_diff_vs_pytorch == pytest.approx(stored, rel=1e-2, abs=1e-12)
        assert 0 <= row.max_abs_diff_vs_pytorch <= 1e-3
    assert (table.onnxruntime_ms_per_frame > 0).all() and (table.pytorch_ms_per_frame > 0).all()
    assert (table.threads == 1).all() and table.hardware.str.contains("1 thread").all()


@pytest.mark.parametrize("variant", DEPLOYED)
def test_the_file_renders_what_pytorch_renders_on_fresh_samples(deployed, variant):
    inputs, outputs, fresh = deployed
    model = load_model(inputs[f"checkpoint_{variant}"], torch.device("cpu"))
    batch = {"light": fresh.light, **fresh.buffers}  # 3 samples: a batch size never exported
    x = graph_inputs(model, batch)
    with torch.inference_mode():
        expected = NDRGraph(model)(*x).numpy()
        assert np.allclose(expected, model(batch)["I_R"].numpy())  # the graph is the model
    got = OnnxNetwork(outputs["onnx"][DEPLOYED.index(variant)])(*(t.numpy() for t in x))
    assert got.shape == (3, 3, WIDTH, WIDTH)
    np.testing.assert_allclose(got, expected, rtol=1e-4, atol=1e-4)


def _shipped_reference(model, sample: dict[str, torch.Tensor], index: int) -> np.ndarray:
    """``I_R`` ``(1, 3, W, W)`` of NDR in PyTorch on ``sample`` under the map of test
    sample ``index`` (drawn again from :data:`SHIPPED_CFG`), its coarse shading computed
    as the data stage computes the prefiltered one (float64, from the map's lighting) and
    its light features from the map's SH: the path the shipped graph fuses."""
    _, env, _, _ = data.sample_scene(SHIPPED_CFG, "test", index)
    view = -pixel_rays(camera(SHIPPED_CFG["camera_distance"], SHIPPED_CFG["fov"]), WIDTH)
    g = {
        "mask": sample["mask"][0].numpy(),
        "normal": sample["N"].permute(1, 2, 0).numpy(),
        "roughness": sample["R"][0].numpy(),
        "view_dir": view.reshape(WIDTH, WIDTH, 3).astype(np.float32),
    }
    cfg = SHIPPED_CFG | {"coarse_shading": "prefiltered"}
    lighting = data.coarse_lighting(cfg, env)
    s_d, s_s = data.coarse_maps(cfg, g, env, lighting=lighting)
    batch = {k: v[None] for k, v in sample.items()}
    batch["S_D"] = torch.from_numpy(s_d).permute(2, 0, 1)[None]
    batch["S_S"] = torch.from_numpy(s_s).permute(2, 0, 1)[None]
    batch["light"] = light_features(lighting.coefficients.reshape(1, -1).numpy())
    with torch.inference_mode():
        return model(batch)["I_R"].numpy()


def test_the_shipped_graph_renders_what_ndr_and_its_coarse_shading_render(deployed):
    """On fresh samples, each under another map, the float32 shipped graph gives NDR's
    ``I_R`` from the prefiltered shading the data stage computes; the int8 graph stays
    near it."""
    inputs, outputs, fresh = deployed
    model = load_model(inputs["checkpoint_ndr"], torch.device("cpu"))
    graphs = {k: OnnxNetwork(outputs[k]) for k in ("shipped", "shipped_int8")}
    assert graphs["shipped"].inputs == graphs["shipped_int8"].inputs == list(SHIPPED_INPUTS)
    stored = float(onnx_metadata(outputs["shipped"])["neurender.max_abs_diff_vs_pytorch"])
    assert 0 <= stored <= 1e-3
    for index in range(len(fresh)):
        sample = fresh[index]
        x = graph_scores.graph_inputs(SHIPPED_CFG, model, "test", index, sample)
        x = [t.numpy() for t in x]
        expected = _shipped_reference(model, sample, index)
        got = graphs["shipped"](*x)
        assert got.shape == (1, 3, WIDTH, WIDTH)
        # I_R is linear HDR radiance (up to 16 here): the tolerance scales with it.
        atol = 1e-4 * max(1.0, np.abs(expected).max())
        np.testing.assert_allclose(got, expected, rtol=0, atol=atol)
        int8 = graphs["shipped_int8"](*x)
        assert np.abs(int8 - got).mean() <= 0.01 * np.abs(got).mean()


def test_the_int8_graph_is_calibrated_on_the_first_training_samples(deployed, tmp_path):
    """Calibrated again on the training split, the float32 graph gives the deployed int8
    graph's output; calibrated on the test split it does not."""
    inputs, outputs, fresh = deployed
    model = load_model(inputs["checkpoint_ndr"], torch.device("cpu"))
    x = [t.numpy() for t in graph_scores.graph_inputs(SHIPPED_CFG, model, "test", 0, fresh[0])]
    deployed_int8 = OnnxNetwork(outputs["shipped_int8"])(*x)
    for split, same in (("train", True), ("test", False)):
        files = {k: inputs[f"{split}_{k}"] for k in ("dir", "manifest", "lighting")}
        again = str(tmp_path / f"{split}.onnx")
        split_data = NDRDataset.from_files(files, 0)
        deploy.export_shipped_int8(SHIPPED_CFG, model, split_data, outputs["shipped"], again)
        got = OnnxNetwork(again)(*x)
        assert np.array_equal(got, deployed_int8) == same, split
