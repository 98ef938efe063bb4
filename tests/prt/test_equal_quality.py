"""DeepPRT's deployment rows: the evaluation's own times of each network beside its file."""

import math

import numpy as np
import pandas as pd
import pytest

from neurender.equal_quality import LOWER, WITHIN
from neurender.nn.inference import onnx_metadata
from neurender.prt.equal_quality import deployment_rows, inference_seconds, network_row
from neurender.prt.frames import Split
from neurender.prt.model import DeepPRT, export_deepprt
from neurender.prt.training import train_deepprt


@pytest.fixture(scope="module")
def shipped(tmp_path_factory, prt_params):
    """A diffuse network trained for one epoch on 8 x 8 frames, and its ONNX file."""
    tmp = tmp_path_factory.mktemp("deepprt")
    rng = np.random.default_rng(3)

    def split(frames):
        shape = (frames, 8, 8)
        return Split(
            rng.normal(size=(*shape, 3)).astype(np.float32),
            rng.normal(size=(*shape, 3)).astype(np.float32),
            rng.uniform(0, 1, (*shape, 16)).astype(np.float32),
            rng.uniform(0, 1, (*shape, 3, 16)).astype(np.float32),
            rng.uniform(0, 1, (frames, 2)),
        )

    train, val = split(4), split(2)
    cfg = prt_params("prt_train", material="diffuse", variant="paper")
    checkpoint, onnx_file = tmp / "net.pt", tmp / "net.onnx"
    train_deepprt(train, val, "diffuse", cfg, 1, str(checkpoint), str(tmp / "loss.csv"))
    export_deepprt(checkpoint, val, onnx_file)
    return checkpoint, str(onnx_file), val


def test_a_row_per_network_with_the_times_it_was_given(shipped):
    checkpoint, onnx_file, test = shipped
    net = DeepPRT(checkpoint, onnx_file, device="cpu")
    seconds = inference_seconds(net, test)
    assert set(seconds) == {"onnxruntime", "pytorch"} and min(seconds.values()) > 0
    (row,) = deployment_rows(
        "head", {"diffuse": net}, {"diffuse": onnx_file}, {"diffuse": seconds}, test, 1
    )
    assert (row["method"], row["network"], row["resolution"]) == (
        "prt",
        "head diffuse (DeepPRT)",
        "8x8",
    )
    assert row["parameters"] == net.parameters and row["onnx_file"] == onnx_file
    with open(onnx_file, "rb") as f:
        assert row["onnx_bytes"] == len(f.read())
    stored = onnx_metadata(onnx_file)["neurender.max_abs_diff_vs_pytorch"]
    assert row["max_abs_diff_vs_pytorch"] == float(stored) <= 1e-4
    assert row["onnxruntime_ms_per_frame"] == 1000 * seconds["onnxruntime"]
    assert row["pytorch_ms_per_frame"] == 1000 * seconds["pytorch"]
    assert row["threads"] == 1 and row["hardware"].endswith("1 thread")


def test_a_network_run_by_pytorch_alone_has_no_onnx_runtime_time(shipped):
    checkpoint, onnx_file, test = shipped
    net = DeepPRT(checkpoint, device="cpu")  # as on a GPU: PyTorch is the only engine
    (row,) = deployment_rows(
        "head", {"diffuse": net}, {"diffuse": onnx_file}, {"diffuse": {"pytorch": 0.002}}, test, 1
    )
    assert math.isnan(row["onnxruntime_ms_per_frame"]) and row["pytorch_ms_per_frame"] == 2.0


def test_each_variant_is_named_in_its_deployment_row(shipped):
    checkpoint, onnx_file, test = shipped
    net = DeepPRT(checkpoint, onnx_file, device="cpu")
    times = {"diffuse": {"pytorch": 0.002, "onnxruntime": 0.001}}
    (row,) = deployment_rows(
        "head", {"diffuse": net}, {"diffuse": onnx_file}, times, test, 1, "DeepPRT shadowing"
    )
    assert row["network"] == "head diffuse (DeepPRT shadowing)"


def test_a_networks_side_is_its_shipping_engines_frame_and_its_other_engines(shipped):
    checkpoint, onnx_file, _ = shipped
    net = DeepPRT(checkpoint, onnx_file, device="cpu")  # ships with ONNX Runtime
    row = network_row(net, {"onnxruntime": 0.002, "pytorch": 0.004}, 0.9, 8.0)
    assert row.cost == 2.0 and row.quality == {"ssim_diffuse": 0.9}
    assert row.extra["inference_ms_per_frame_pytorch"] == 4.0
    assert row.extra["speedup_vs_reference_gt"] == pytest.approx(8.0 / 0.002)
    assert "inference_ms_per_frame_onnxruntime" not in row.extra


def test_a_variants_equal_quality_ratio_is_against_the_fastest_count_reaching_its_ssim(
    shipped, monkeypatch
):
    from neurender.prt import equal_quality

    checkpoint, onnx_file, test = shipped
    net = DeepPRT(checkpoint, onnx_file, device="cpu")
    # 256 directions measured faster than 64 (a noisy machine): the faster render of
    # the network's SSIM is the pick, whatever its count.
    estimates = {16: (0.1, 0.80), 64: (0.4, 0.93), 256: (0.3, 0.99)}
    monkeypatch.setattr(equal_quality, "ray_traced_estimates", lambda *args: (estimates, 8.0))
    frames = pd.DataFrame(
        {"split": "test", "metric": "ssim_diffuse", "frame": 0, "model": ["a", "b"]}
    ).assign(value=[0.9, 0.995])
    engine_s = {"onnxruntime": 0.002, "pytorch": 0.004}
    cfg = {"noise_floor_frames": 1}
    table = equal_quality.table(
        "head", {"a": net, "b": net}, {"a": engine_s, "b": engine_s}, test, None, cfg, 1, frames
    )
    picks = table[table.metric == "equal_quality_speedup"].set_index("model")
    assert picks.loc["a", "setting"] == "256 directions" and picks.loc["a", "bound"] == WITHIN
    assert picks.loc["a", "value"] == pytest.approx(0.3 / 0.002)
    # Better than every estimate: a lower bound against the slowest.
    assert picks.loc["b", "setting"] == "64 directions" and picks.loc["b", "bound"] == LOWER
    assert picks.loc["b", "value"] == pytest.approx(0.4 / 0.002)


def _bowl_split(positions):
    """The bowl's geometry images with placeholder transfer."""
    shape = positions.shape[:3]
    return Split(
        positions,
        np.zeros((*shape, 3), np.float32),
        np.full((*shape, 4), 0.3, np.float32),
        np.zeros((*shape, 3, 4), np.float32),
        np.zeros((shape[0], 1)),
    )


@pytest.mark.parametrize("sweep", [[4, 16], [4, 16, 64]])
def test_the_sweep_may_hold_the_references_own_count(sweep, bowl_positions):
    from neurender.prt.equal_quality import ray_traced_estimates

    cfg = {"seed": 0, "n_bands": 2, "direction_sets": 2, "ray_offset": 1e-3}
    cfg |= {"equal_quality_directions": sweep, "reference_directions": 64}
    cfg |= {"render_resolution": 16}
    light = np.full((4, 3), 0.5, np.float32)
    estimates, reference_s = ray_traced_estimates(
        "bowl", _bowl_split(bowl_positions()), 2, light, cfg, 1
    )
    assert sorted(estimates) == sweep  # every count scored, the reference's too
    assert all(np.isfinite(ssim) and seconds > 0 for seconds, ssim in estimates.values())
    assert reference_s > 0
    if 64 in sweep:
        assert reference_s == estimates[64][0]  # the same work, not traced twice


def test_a_ray_traced_time_is_the_median_frame_after_an_uncounted_warm_up(
    monkeypatch, bowl_positions
):
    from neurender.prt import equal_quality

    # Each trace takes the next of these seconds: the warm-up's 9 s, then three frames
    # of which one is slow; the median frame is 2 s (the mean 4 s, with the warm-up 5.25).
    durations = iter([9.0, 1.0, 9.0, 2.0])
    clock = {"now": 0.0}
    monkeypatch.setattr(equal_quality.time, "perf_counter", lambda: clock["now"])

    def traced(positions, *args):
        clock["now"] += next(durations)
        return None, np.zeros(positions.shape[:2] + (4,), np.float32), None, None

    monkeypatch.setattr(equal_quality.transfer, "sample_frame", traced)
    monkeypatch.setattr(equal_quality, "diffuse_ssim", lambda *args: 0.5)
    cfg = {"ray_offset": 1e-3, "render_resolution": 16}
    cfg |= {"equal_quality_directions": [16], "reference_directions": 16}
    light = np.full((4, 3), 0.5, np.float32)
    estimates, reference_s = equal_quality.ray_traced_estimates(
        "bowl", _bowl_split(bowl_positions(frames=3)), 3, light, cfg, 1
    )
    assert estimates == {16: (2.0, 0.5)}
    assert reference_s == 2.0
