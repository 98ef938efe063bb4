"""NDR against Mitsuba at equal quality: the pick, the scores and the job."""

import numpy as np
import pandas as pd
import pytest
import torch

from neurender import equal_quality as shared
from neurender import io
from neurender.ndr import data, deploy, evaluate, graph_scores, jobs, summary
from neurender.ndr import equal_quality as eq
from neurender.ndr.buffers import NDRDataset
from neurender.ndr.evaluate import NOISE_FLOOR, score_split
from neurender.ndr.model import NDRModel, compose, load_model
from neurender.ndr.variants import VARIANTS
from neurender.nn.inference import OnnxNetwork
from neurender.tables import tidy_rows

#: A tiny complex-data config (16 x 16 images, 2 test samples).
CFG = {
    "seed": 5,
    "device": "cpu",
    "width": 16,
    "camera_distance": 3.9,
    "fov": 30.0,
    "primitives": [2, 3],
    "edge_length": 0.3,
    "environment_height": 16,
    "coarse_height": 8,
    "coarse_shading": "importance",
    "coarse_samples": 16,
    "bright_texels": 16,
    "spp": 4,
    "reference_spp": 64,
    "fixed_probe": "sky",
    "user_probes_dir": "",
    "user_probe_fraction": 0.5,
    "small_sun_fraction": 0.3,
}


def _scores(rows: list[tuple[int, float, float]]) -> pd.DataFrame:
    """A hand-made sweep: ``(spp, ms_per_frame, dssim_I_R)`` per row (scenes built in 1 ms)."""
    return pd.DataFrame(rows, columns=["spp", "ms_per_frame", eq.METRIC]).assign(scene_ms=1.0)


SWEEP = _scores([(1, 2.0, 0.20), (4, 5.0, 0.10), (16, 17.0, 0.05), (64, 65.0, 0.02)])


def test_the_pick_is_the_shared_rule_on_the_spp_sweep():
    """:func:`neurender.equal_quality.pick` on the sample counts, labelled by spp."""
    assert eq.pick(SWEEP, 0.07) == shared.Pick("16 spp", 17.0, shared.WITHIN)
    assert eq.pick(SWEEP, 0.10) == shared.Pick("4 spp", 5.0, shared.WITHIN)
    assert eq.pick(SWEEP, 0.01) == shared.Pick("64 spp", 65.0, shared.LOWER)
    assert eq.pick(SWEEP, 0.3) == shared.Pick("1 spp", 2.0, shared.UPPER)


def test_the_sweep_adds_the_training_spp_and_refuses_counts_below_one():
    assert eq.sweep([16, 1, 4], 8) == [1, 4, 8, 16]
    assert eq.sweep([1, 8], 8) == [1, 8]
    with pytest.raises(ValueError, match="equal_quality_spp"):
        eq.sweep([0, 4], 8)


def _network(dssim: float) -> dict[str, dict[str, float]]:
    return {
        eq.NETWORK: {
            "coarse_shading_ms": 1.0,
            "network_ms": 1.5,
            "ms_per_frame": 2.5,
            eq.METRIC: dssim,
        }
    }


def test_the_table_states_both_ratios_and_the_pick():
    table = eq.table(SWEEP, _network(0.07), 16)
    ndr = table[table.model == eq.NETWORK].set_index("metric")["value"]
    assert ndr["speedup_vs_training_spp"] == pytest.approx(17.0 / 2.5)
    assert ndr["equal_quality_speedup"] == pytest.approx(17.0 / 2.5)
    assert ndr["equal_quality_reference_ms"] == 17.0 and ndr["training_spp"] == 16
    assert set(table[table.model == eq.NETWORK].setting) == {"16 spp"}
    mitsuba = table[table.model == eq.MITSUBA]
    assert set(mitsuba.setting) == {"1 spp", "4 spp", "16 spp", "64 spp"}
    assert len(mitsuba) == 3 * len(SWEEP)  # ms_per_frame, scene_ms, DSSIM
    unreached = eq.table(SWEEP, _network(0.01), 16)
    row = unreached[unreached.model == eq.NETWORK]
    assert set(row.setting) == {"64 spp"} and set(row.bound) == {shared.LOWER}
    value = row.set_index("metric")["value"]
    assert value["equal_quality_speedup"] == pytest.approx(65.0 / 2.5)


def test_each_graph_is_compared_with_the_cheapest_render_of_its_own_dssim():
    """The int8 graph: faster and slightly worse than the float32 one, so its pick may be
    a more expensive render; each ratio is against its own pick."""
    networks = _network(0.10) | {eq.NETWORK_INT8: {"ms_per_frame": 1.0, eq.METRIC: 0.07}}
    table = eq.table(SWEEP, networks, 16)
    rows = {n: table[table.model == n].set_index("metric")["value"] for n in networks}
    picks = table[table.metric == "equal_quality_speedup"].set_index("model")["setting"]
    assert picks.to_dict() == {eq.NETWORK: "4 spp", eq.NETWORK_INT8: "16 spp"}
    assert rows[eq.NETWORK]["equal_quality_speedup"] == pytest.approx(5.0 / 2.5)
    assert rows[eq.NETWORK_INT8]["equal_quality_speedup"] == pytest.approx(17.0 / 1.0)
    assert rows[eq.NETWORK_INT8]["speedup_vs_training_spp"] == pytest.approx(17.0 / 1.0)


def test_the_speed_targets_are_met_only_by_a_pick_or_a_lower_bound():
    metrics = pd.DataFrame(
        [
            r
            for m, v in (("ndr", 0.05), ("shading_input", 0.1))
            for r in tidy_rows("ndr", "complex", m, "test", {"dssim_I_R": v})
        ]
    )

    def checks(target: float, ms: float, int8_ms: float = 1.0) -> pd.Series:
        network = {"coarse_shading_ms": ms / 2, "network_ms": ms / 2, "ms_per_frame": ms}
        networks = {eq.NETWORK: network | {eq.METRIC: target}}
        networks[eq.NETWORK_INT8] = {"ms_per_frame": int8_ms, eq.METRIC: target}
        equal = eq.table(SWEEP, networks, 64)
        table = summary.targets(metrics, equal)
        met = []
        for graph, suffix in ((eq.NETWORK, ""), (eq.NETWORK_INT8, " (int8 graph)")):
            at_training = table.subject == f"Mitsuba at the training 64 spp{suffix}"
            at_equal = table.check.str.startswith(f"{graph} at least 3x faster than the cheapest")
            met += [*table[at_training].met, *table[at_equal].met]
        return pd.Series(met)

    assert checks(0.07, 2.0).tolist() == [True, True] * 2  # 32.5x, 8.5x; int8 65x, 17x
    assert checks(0.07, 4.0).tolist() == [False, True, True, True]  # 16x, 4.25x
    assert checks(0.07, 4.0, 4.0).tolist() == [False, True] * 2
    assert checks(0.01, 4.0, 4.0).tolist() == [False, True] * 2  # lower bound 16x
    assert checks(0.3, 0.5, 0.5).tolist() == [True, False] * 2  # worse than 1 spp: an upper bound


@pytest.fixture(scope="module")
def tiny_split(tmp_path_factory):
    """Two test samples of :data:`CFG` rendered by the data stage: their files and buffers."""
    tmp = tmp_path_factory.mktemp("ndr_equal_quality")
    files = {
        "dir": str(tmp / "test"),
        "manifest": str(tmp / "m.csv"),
        "lighting": str(tmp / "l.csv"),
    }
    data.generate_split(CFG, "test", 2, files["dir"], files["manifest"], files["lighting"], 1)
    train = {k: str(tmp / f"train_{k}") for k in ("dir", "manifest", "lighting")}
    data.generate_split(CFG, "train", 2, train["dir"], train["manifest"], train["lighting"], 1)
    return files, NDRDataset.from_files(files, 1), train


def test_a_render_scored_against_itself_has_dssim_zero(tiny_split):
    _, test, _ = tiny_split
    b = test.buffers
    assert torch.equal(eq.dssim(b["I_D"], b["I_S"], b), torch.zeros(2))
    assert (eq.dssim(b["I_D_noisy"], b["I_S_noisy"], b) > 0).all()


def test_more_samples_per_pixel_lower_the_dssim(mitsuba, tiny_split):
    mi, _ = mitsuba
    _, test, _ = tiny_split
    scenes = [eq.scene_of(CFG, i) for i in range(2)]
    scores = eq.score_sweep(mi, CFG, scenes, test.buffers, [1, 4, 32], repeats=1)
    assert scores[eq.METRIC].is_monotonic_decreasing
    assert scores[eq.METRIC].iloc[0] > 2 * scores[eq.METRIC].iloc[-1]


def test_the_training_spp_render_is_the_noise_floors(mitsuba, tiny_split):
    """Drawn and seeded as the data stage draws the noise-floor render."""
    mi, _ = mitsuba
    _, test, _ = tiny_split
    scene = eq.scene_of(CFG, 1)
    maps = eq.render_maps(mi, eq.load_scene(mi, CFG, scene, CFG["spp"]), scene)
    stored = test[1]["I_D_noisy"].permute(1, 2, 0).numpy()
    np.testing.assert_allclose(maps["I_D"], stored, rtol=1e-5, atol=1e-6)


def test_the_job_writes_every_spp_and_ndrs_scores_on_the_same_samples(tiny_split, tmp_path):
    files, test, train = tiny_split
    split = {f"{part}_{k}": v for part in ("train", "val") for k, v in files.items()}
    params = {"seed": 0, "device": "cpu", "variant": "ndr", "mask_erosion": 1}
    params |= {"epochs": 1, "batch_size": 2, "lr": 1e-3, "lr_schedule": "constant"}
    params |= {"widths": [4, 8], "sh_hidden": 8, "shading_residual": True}
    checkpoint = str(tmp_path / "ndr.pt")
    jobs.ndr_train(split, {"checkpoint": checkpoint, "loss": str(tmp_path / "loss.csv")}, params, 1)
    scored = score_split("complex", test, {"ndr": checkpoint}, torch.device("cpu"))
    samples = str(tmp_path / "samples.csv")
    io.write_csv(samples, pd.DataFrame(scored.per_sample))
    inputs = {f"test_{k}": v for k, v in files.items()} | {"checkpoint": checkpoint}
    inputs["samples"] = samples
    # The shipped graphs as the deploy job writes them.
    model = load_model(checkpoint, torch.device("cpu"))
    inputs["graph"] = str(tmp_path / "ndr_shipped.onnx")
    inputs["graph_int8"] = str(tmp_path / "ndr_shipped_int8.onnx")
    deploy.export_shipped(CFG, model, NDRDataset.from_files(files, 0, 1), inputs["graph"])
    calibration = NDRDataset.from_files(train, 0)
    deploy.export_shipped_int8(CFG, model, calibration, inputs["graph"], inputs["graph_int8"])
    outputs = {"table": str(tmp_path / "eq.csv"), "figure": str(tmp_path / "eq.png")}
    cfg = CFG | {"equal_quality_spp": [1, 16], "equal_quality_samples": 2, "mask_erosion": 1}
    jobs.ndr_equal_quality(inputs, outputs, cfg, 1)

    table = io.read_csv(outputs["table"])
    mitsuba = table[table.model == eq.MITSUBA]
    assert set(mitsuba.setting) == {"1 spp", "4 spp", "16 spp"}  # the training 4 added
    assert set(mitsuba.metric) == {"ms_per_frame", "scene_ms", eq.METRIC}
    assert (mitsuba[mitsuba.metric == "ms_per_frame"].value > 0).all()
    per_sample = pd.DataFrame(scored.per_sample)
    dssim = per_sample[per_sample.metric == eq.METRIC].groupby("model")["value"].mean()
    ndr = table[(table.model == eq.NETWORK) & (table.split == eq.SPLIT)]
    ndr = ndr.set_index("metric")["value"]
    assert ndr[eq.METRIC] == pytest.approx(dssim["ndr"])
    train = mitsuba[(mitsuba.setting == "4 spp")].set_index("metric")["value"]
    assert train[eq.METRIC] == pytest.approx(dssim[NOISE_FLOOR], rel=1e-4)
    assert ndr["speedup_vs_training_spp"] == pytest.approx(
        train["ms_per_frame"] / ndr["ms_per_frame"]
    )
    # Trained on importance-sampled shading: NDR's frame is that shading and the network;
    # the shipped graph (its own, prefiltered shading) is timed beside it.
    assert ndr["ms_per_frame"] == pytest.approx(ndr["coarse_shading_ms"] + ndr["network_ms"])
    assert ndr["shipped_graph_ms"] > 0
    # The int8 graph: its own frame time and DSSIM, the latter the mean of its scores on
    # the same samples of the whole test split.
    int8 = table[(table.model == eq.NETWORK_INT8) & (table.split == eq.SPLIT)]
    int8 = int8.set_index("metric")["value"]
    assert int8["ms_per_frame"] == pytest.approx(ndr["shipped_int8_graph_ms"])
    whole = table[(table.split == eq.GRAPH_SPLIT) & (table.dataset == "complex")]
    assert set(whole.model) == {eq.NETWORK, eq.NETWORK_INT8}
    assert whole.set_index(["model", "metric"]).loc[(eq.NETWORK_INT8, eq.METRIC), "value"] == (
        pytest.approx(int8[eq.METRIC])  # both test samples are the sweep's
    )
    assert open(outputs["figure"], "rb").read(4) == b"\x89PNG"

    with pytest.raises(ValueError, match="equal_quality_samples = 3"):
        jobs.ndr_equal_quality(inputs, outputs, cfg | {"equal_quality_samples": 3}, 1)


def test_the_shipped_graph_scores_what_the_network_scores_on_prefiltered_data(tmp_path):
    """On ``coarse_shading: prefiltered`` data the one-graph NDR (its shading from the
    sample's G-buffers and map) gives the network's ``I_R`` on the stored sample, and its
    scores are the evaluation's (PyTorch on the stored buffers); its int8 graph
    (calibrated on a training split) approximates it."""
    cfg = CFG | {"coarse_shading": "prefiltered"}
    splits = {}
    for split in ("test", "train"):
        files = {k: str(tmp_path / f"{split}_{k}") for k in ("dir", "manifest", "lighting")}
        data.generate_split(cfg, split, 2, files["dir"], files["manifest"], files["lighting"], 1)
        splits[split] = NDRDataset.from_files(files, 0)  # masks uneroded, as a renderer has
    test = splits["test"]
    torch.manual_seed(0)
    model = NDRModel(VARIANTS["ndr"], widths=[4, 8], sh_hidden=8).eval()
    graph, int8 = tmp_path / "shipped.onnx", tmp_path / "shipped_int8.onnx"
    deploy.export_shipped(cfg, model, test, str(graph))
    deploy.export_shipped_int8(cfg, model, splits["train"], str(graph), str(int8))
    inputs = graph_scores.graph_inputs(cfg, model, "test", 0, test[0])
    shipped = OnnxNetwork(graph)(*[x.numpy() for x in inputs])
    with torch.inference_mode():
        stored = model({k: v[None] for k, v in test[0].items()})["I_R"].numpy()
    assert np.abs(shipped - stored).max() <= 1e-3 * max(1.0, np.abs(stored).max())

    sessions = {"float32": OnnxNetwork(graph), "int8": OnnxNetwork(int8)}
    both = graph_scores.score_graphs(cfg, model, sessions, "test", test, 1)
    scores, quantized = both["float32"], both["int8"]
    files = {k: str(tmp_path / f"test_{k}") for k in ("dir", "manifest", "lighting")}
    eroded = NDRDataset.from_files(files, 1).buffers  # as the evaluation reads the split
    pred = evaluate.predict(model, NDRDataset.from_files(files, 1), torch.device("cpu"))
    truth = compose(eroded["I_D"], eroded["I_S"], eroded)
    expected = evaluate.score(pred, truth, eroded["mask"])[eq.METRIC]
    torch.testing.assert_close(scores[eq.METRIC], expected, atol=1e-4, rtol=0)
    assert (quantized[eq.METRIC] - scores[eq.METRIC]).abs().max() < 0.02
