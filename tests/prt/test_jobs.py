from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from neurender import io, sh, train
from neurender.jobs import copy_files, input_name
from neurender.prt import data_jobs, frames, jobs
from neurender.prt.local_model import ShadowingTransfer
from neurender.prt.model import DeepPRT, TransferNetwork, load_transfer_module


@pytest.fixture(scope="module")
def head(tmp_path_factory, prt_params):
    d = tmp_path_factory.mktemp("head")
    probe = {"exr": d / "sky.exr", "sh": d / "sky_sh.csv"}
    data_jobs.prt_probe({}, probe, prt_params("prt_probe", probe="sky"), 1)
    gim_out = {"gim": d / "gim.npz", "stats": d / "gim.csv"}
    data_jobs.prt_geometry_image({}, gim_out, prt_params("prt_geometry_image", object="head"), 1)
    data_jobs.prt_sequence(
        {"gim": d / "gim.npz"}, {"seq": d / "seq.npz"}, prt_params("prt_sequence", object="head"), 1
    )
    return d


#: The directions of :func:`_transfer`'s test frames (the workflow's are the reference's).
TEST_DIRECTIONS = 16


def _transfer(prt_params, head, light, run, threads):
    """Test frames of the head with :data:`TEST_DIRECTIONS` directions into ``head / run``."""
    data_jobs.prt_transfer(
        {"seq": head / "seq.npz", "light": head / light},
        {"frames": head / run, "manifest": head / f"{run}.csv"},
        prt_params("prt_transfer", object="head", split="test") | {"directions": TEST_DIRECTIONS},
        threads,
    )


def test_probe_sh_matches_projection(head):
    img = np.stack([io.read_exr(head / "sky.exr")[c] for c in "RGB"], -1)
    np.testing.assert_allclose(
        frames.read_sh_light(head / "sky_sh.csv"), sh.project_latlong(img, 4), rtol=1e-5
    )


def test_probe_sh_first_bands_are_the_lower_order_projection(head):
    img = np.stack([io.read_exr(head / "sky.exr")[c] for c in "RGB"], -1)
    np.testing.assert_allclose(
        frames.read_sh_light(head / "sky_sh.csv", 2), sh.project_latlong(img, 2), rtol=1e-5
    )


def test_a_user_probe_without_positive_radiance_stops_its_job_naming_file_and_key(
    tmp_path, prt_params
):
    source = tmp_path / "night.exr"
    io.write_exr(source, {c: np.full((8, 16), -0.1, np.float32) for c in "RGB"})
    outputs = {"exr": tmp_path / "out.exr", "sh": tmp_path / "out_sh.csv"}
    with pytest.raises(ValueError) as caught:
        data_jobs.prt_probe({"source": source}, outputs, prt_params("prt_probe", probe="night"), 1)
    message = str(caught.value)
    assert f"light probe {source} (prt.user_probes.night) has no positive radiance" in message
    assert "expected a map with positive radiance" in message
    assert not outputs["exr"].exists()


def test_sequence_splits_and_extrapolation(head):
    seq = io.load_npz(head / "seq.npz")
    assert seq["train_positions"].shape == (3, 8, 8, 3)
    assert seq["test_params"].shape == (2, 7)
    assert seq["test_params"][seq["test_extrapolated"]].max() > 1.0  # beyond the training range
    assert seq["train_params"].max() <= 1.0
    assert not set(seq["train_frame"]) & set(seq["val_frame"])


def test_transfer_frames_are_deterministic_and_complete(head, prt_params):
    for run in ("a", "b"):
        _transfer(prt_params, head, "sky_sh.csv", run, 2)
    manifest = pd.read_csv(head / "a.csv")
    assert list(manifest.frame) == [0, 1] and (manifest.rays > 0).all()
    assert manifest.extrapolated.tolist() == [False, True]
    a = frames.read_frame(head / "a" / "frame_0001.exr", 4)
    b = frames.read_frame(head / "b" / "frame_0001.exr", 4)
    for key in ("P", "N", "T", "G"):
        np.testing.assert_array_equal(a[key], b[key])
    assert a["T"].shape == (8, 8, 16) and a["G"].shape == (8, 8, 3, 16)
    np.testing.assert_allclose(a["P"], io.load_npz(head / "seq.npz")["test_positions"][1])


def test_missing_light_file_is_named(head, prt_params):
    with pytest.raises(FileNotFoundError, match="nolight.csv"):
        _transfer(prt_params, head, "nolight.csv", "x", 1)


@pytest.mark.parametrize("name", ["head_linear", "head_excluded"])
def test_experiment_sequences(head, prt_params, name):
    params = prt_params("prt_sequence", object=name)
    data_jobs.prt_sequence({"gim": head / "gim.npz"}, {"seq": head / f"{name}.npz"}, params, 1)
    seq = io.load_npz(head / f"{name}.npz")
    assert len(seq["train_positions"]) == 2 and len(seq["test_positions"]) == 3
    if name == "head_linear":
        np.testing.assert_allclose(seq["test_params"][:, 0], [-0.25, 0.5, 1.25])
        assert seq["test_extrapolated"].tolist() == [True, False, True]
        # a = 0 is the flat plane, a = 1 the neutral head
        rest = io.load_npz(head / "gim.npz")["rest"]
        mid = 0.5 * rest
        mid[..., :2] = rest[..., :2]
        np.testing.assert_allclose(seq["test_positions"][1], mid, atol=1e-5)
    else:
        k = 2  # jaw_open
        assert (seq["train_params"][:, k] == 0).all()
        np.testing.assert_allclose(seq["test_params"][-1], np.eye(7)[k], atol=1e-6)


@pytest.fixture(scope="module")
def trained(head, prt_params):
    """The head's train and val frames, and one network of every variant and material
    trained by the job as the rule calls it (the paper's form gets its own key)."""
    inputs = {"seq": head / "seq.npz"}
    for split in ("train", "val"):
        data_jobs.prt_transfer(
            {"seq": head / "seq.npz", "light": head / "sky_sh.csv"},
            {"frames": head / split, "manifest": head / f"{split}_manifest.csv"},
            prt_params("prt_transfer", object="head", split=split),
            1,
        )
        inputs |= {
            f"{split}_dir": head / split,
            f"{split}_manifest": head / f"{split}_manifest.csv",
        }
    out = head / "variants"
    files = {}
    for variant, material in [
        ("paper", "diffuse"),
        ("shadowing", "diffuse"),
        ("shadowing", "glossy"),
    ]:
        extra = {"light": head / "sky_sh.csv"} if material == "glossy" else {}
        files[variant, material] = _train_and_deploy(
            prt_params, {**inputs, **extra}, out / f"{variant}_{material}", head, variant, material
        )
    return inputs, files


def _train_and_deploy(
    prt_params, inputs: dict, stem: Path, head: Path, variant: str, material: str
) -> dict:
    """A network of the head trained and deployed by the jobs as the rules call them: its
    files."""
    board = head / "tensorboard" / stem.name / "run.json"
    trained = {"checkpoint": f"{stem}.pt", "loss": f"{stem}_loss.csv", "tensorboard": str(board)}
    wildcards = {"variant": variant, "material": material}
    jobs.prt_train(inputs, trained, prt_params("prt_train", **wildcards), 1)
    graphs = {"onnx": f"{stem}.onnx", "int8": f"{stem}_int8.onnx"}
    params = prt_params("prt_deploy", object="head", **wildcards)
    jobs.prt_deploy({**inputs, "checkpoint": trained["checkpoint"]}, graphs, params, 1)
    return trained | graphs


@pytest.mark.parametrize(
    ("variant", "material", "module"),
    [
        ("paper", "diffuse", TransferNetwork),
        ("shadowing", "diffuse", ShadowingTransfer),
        ("shadowing", "glossy", ShadowingTransfer),
    ],
)
def test_each_variant_trains_into_a_checkpoint_both_engines_serve(
    trained, head, variant, material, module
):
    inputs, files = trained
    outputs = files[variant, material]
    assert isinstance(load_transfer_module(outputs["checkpoint"]), module)
    seq = io.load_npz(inputs["seq"])
    val = frames.load_split(inputs["val_dir"], inputs["val_manifest"], seq["val_params"], 4)
    net = DeepPRT(outputs["checkpoint"], outputs["onnx"], device="cpu")
    torch_pred, onnx_pred = (net.predict(val, engine=e) for e in ("pytorch", "onnxruntime"))
    assert torch_pred.shape == val.targets(material).shape  # (F, C, n, n)
    np.testing.assert_allclose(onnx_pred, torch_pred, rtol=1e-4, atol=1e-5)
    assert io.read_csv(outputs["loss"]).epoch.max() == 1
    int8 = DeepPRT(outputs["checkpoint"], outputs["int8"], device="cpu", pytorch=False)
    assert int8.predict(val).shape == torch_pred.shape  # the same contract, ONNX Runtime alone


def test_a_split_loads_its_first_frames_in_frame_order(trained):
    inputs, _ = trained
    seq = io.load_npz(inputs["seq"])
    whole = frames.split_frames(inputs, seq, "train", 4)
    assert len(whole.positions) > 2
    first = frames.split_frames(inputs, seq, "train", 4, first=2)
    for name in ("positions", "normals", "diffuse", "glossy", "params"):
        np.testing.assert_array_equal(getattr(first, name), getattr(whole, name)[:2])
    beyond = frames.split_frames(inputs, seq, "train", 4, first=len(whole.positions) + 5)
    np.testing.assert_array_equal(beyond.glossy, whole.glossy)


def test_deploy_writes_the_graphs_exported_from_the_whole_splits(trained, head, tmp_path):
    """The deploy job reads only the frames its exports use: its graphs predict as the
    graphs exported from the whole val and train splits do."""
    from neurender.prt.model import export_deepprt, export_int8

    inputs, files = trained
    source = files["shadowing", "glossy"]
    seq = io.load_npz(inputs["seq"])
    val, train_split = (frames.split_frames(inputs, seq, s, 4) for s in ("val", "train"))
    export_deepprt(source["checkpoint"], val, tmp_path / "whole.onnx")
    export_int8(tmp_path / "whole.onnx", train_split, tmp_path / "whole_int8.onnx")
    for deployed, whole in ((source["onnx"], "whole.onnx"), (source["int8"], "whole_int8.onnx")):
        ours, theirs = (
            DeepPRT(source["checkpoint"], graph, device="cpu", pytorch=False)
            for graph in (deployed, tmp_path / whole)
        )
        np.testing.assert_array_equal(ours.predict(val), theirs.predict(val))


@pytest.mark.parametrize(
    ("variant", "keys"),
    [("paper", ("batch_size", "lr")), ("shadowing", ("shadowing_batch_size", "shadowing_lr"))],
)
def test_each_variant_trains_with_its_own_batch_size_and_learning_rate(
    trained, prt_params, variant, keys
):
    _, files = trained
    config = train.load_checkpoint(files[variant, "diffuse"]["checkpoint"])["config"]
    params = prt_params("prt_train", material="diffuse", variant=variant)
    assert (config["batch_size"], config["lr"]) == tuple(params[k] for k in keys)


def test_an_unknown_variant_is_refused_naming_it(trained, head, prt_params):
    inputs, _ = trained
    params = prt_params("prt_train", material="diffuse", variant="tiny")
    outputs = {"checkpoint": head / "x.pt", "loss": head / "x.csv"}
    with pytest.raises(
        ValueError, match=r"variant 'tiny'; expected one of \['paper', 'shadowing'\]"
    ):
        jobs.prt_train(inputs, outputs, params, 1)


def test_ship_copies_the_shipped_variants_bytes(trained, head, prt_params):
    _, files = trained
    source = files["shadowing", "diffuse"]
    outputs = {"checkpoint": head / "deepprt_diffuse.pt", "onnx": head / "deepprt_diffuse.onnx"}
    inputs = {"checkpoint": source["checkpoint"], "onnx": source["onnx"]}
    copy_files(inputs, outputs, prt_params("prt_ship"), 1)
    for key in ("checkpoint", "onnx"):
        with open(outputs[key], "rb") as got, open(source[key], "rb") as want:
            assert got.read() == want.read()
    assert isinstance(load_transfer_module(outputs["checkpoint"]), ShadowingTransfer)


@pytest.mark.parametrize("variant", ["paper", "shadowing"])
def test_each_variant_logs_its_epochs_and_previews_to_tensorboard(
    trained, variant, tensorboard_steps
):
    _, files = trained
    logged = tensorboard_steps(Path(files[variant, "diffuse"]["tensorboard"]).parent)
    assert logged["val/loss"] == logged["previews/prediction"] == logged["lr"] == [1]


@pytest.fixture(scope="module")
def evaluated(trained, head, prt_params):
    """Every network (the paper's glossy one too), MoMoPRT, the test references at the
    reference's directions, and the evaluation and equal-quality jobs run as the rules run
    them (the first on one thread, the second on two)."""
    inputs, files = trained
    stem = head / "variants" / "paper_glossy"
    paper_glossy = _train_and_deploy(prt_params, inputs, stem, head, "paper", "glossy")
    files = {**files, ("paper", "glossy"): paper_glossy}
    data_jobs.prt_transfer(
        {"seq": head / "seq.npz", "light": head / "sky_sh.csv"},
        {"frames": head / "test", "manifest": head / "test_manifest.csv"},
        prt_params("prt_transfer", object="head", split="test"),
        1,
    )
    momoprt = {}
    for material in ("diffuse", "glossy"):
        out = {"model": head / f"momoprt_{material}.npz"}
        data_jobs.prt_momoprt(inputs, out, prt_params("prt_momoprt", material=material), 1)
        momoprt[input_name("momoprt", material)] = out["model"]
    params = prt_params("prt_evaluate", object="head")
    pairs = [(v, m) for v in params["variants"] for m in ("diffuse", "glossy")]
    networks = {
        input_name(kind, *p): files[p][name]
        for kind, name in (("pt", "checkpoint"), ("onnx", "onnx"), ("int8.onnx", "int8"))
        for p in pairs
    }
    test = {"test_dir": head / "test", "test_manifest": head / "test_manifest.csv"}
    light = {"light": head / "sky_sh.csv"}
    scores = {"metrics": head / "metrics.csv", "frames": head / "metrics_frames.csv"}
    evaluate_inputs = {**inputs, **test, **networks, **light, **momoprt}
    jobs.prt_evaluate(evaluate_inputs, {**scores, "figure": head / "prediction.png"}, params, 1)
    timed = {"equal_quality": head / "equal_quality.csv", "deployment": head / "deployment.csv"}
    equal_inputs = {"seq": inputs["seq"], **test, **networks, **light, "frames": scores["frames"]}
    jobs.prt_equal_quality(equal_inputs, timed, prt_params("prt_equal_quality", object="head"), 2)
    return {name: io.read_csv(path) for name, path in {**scores, **timed}.items()}


def test_evaluation_scores_every_network_momoprt_and_the_ground_truths_on_val_and_test(
    evaluated,
):
    frames_ = evaluated["frames"]
    ssim = frames_[frames_.metric == "ssim_diffuse"]
    # Both splits' frames (one val, two test) for every network, int8 graph and MoMoPRT;
    # the independent ground-truth estimates on the test frames only.
    networks = {"DeepPRT", "DeepPRT shadowing", "MoMoPRT"}
    networks |= {f"{m} int8" for m in ("DeepPRT", "DeepPRT shadowing")}
    for model in networks:
        rows = ssim[ssim.model == model]
        pairs = sorted(zip(rows.split, rows.frame, strict=True))
        assert pairs == [("test", 0), ("test", 1), ("val", 0)]
    estimates = {"ground truth 16 dirs", "ground truth 64 dirs"}
    assert set(ssim.model) == networks | estimates
    assert set(ssim[ssim.model.isin(estimates)].split) == {"test"}
    assert ssim.value.between(-1, 1).all()
    # The means are the per-frame scores' means.
    scores = evaluated["metrics"]
    mean = scores[(scores.model == "MoMoPRT") & (scores.metric == "ssim_diffuse")]
    mean = mean[mean.split == "test"].value.item()
    want = ssim[(ssim.model == "MoMoPRT") & (ssim.split == "test")].value.mean()
    assert mean == pytest.approx(want)


def test_every_network_records_its_training_budget(evaluated, prt_params):
    scores = evaluated["metrics"]
    budget = scores[scores.metric.str.startswith("epochs_")]
    assert set(budget.model) == {"DeepPRT", "DeepPRT shadowing", "DeepPRT int8"} | {
        "DeepPRT shadowing int8"
    }
    epochs = prt_params("prt_train", material="diffuse", variant="paper")["epochs"]
    assert (budget.value == epochs).all() and len(budget) == 4 * 2


def test_equal_quality_times_every_direction_count_and_picks_by_the_shared_rule(
    evaluated, prt_params
):
    from neurender import equal_quality as shared
    from neurender.prt.equal_quality import QUALITY, RAY_TRACED

    table = evaluated["equal_quality"]
    assert set(table.split) == {shared.SPLIT} and set(table.dataset) == {"head"}
    traced = table[table.model == RAY_TRACED]
    params = prt_params("prt_equal_quality", object="head")
    counts = params["equal_quality_directions"]
    assert set(traced.setting) == {f"{d} directions" for d in counts}
    assert (traced[traced.metric == "ms_per_frame"].value > 0).all()
    scores = traced.pivot_table(index="setting", columns="metric", values="value").reset_index()
    frames_ = evaluated["frames"]
    for model in ("DeepPRT", "DeepPRT shadowing", "DeepPRT int8", "DeepPRT shadowing int8"):
        mine = table[table.model == model]
        value = mine.set_index("metric")["value"]
        # Its SSIM: its mean diffuse SSIM on the same first test frames as the estimates.
        ssim = frames_[
            (frames_.model == model)
            & (frames_.metric == "ssim_diffuse")
            & (frames_.split == "test")
            & (frames_.frame < params["noise_floor_frames"])
        ]
        assert value["ssim_diffuse"] == pytest.approx(ssim.value.mean())
        pick = shared.pick(scores, {"ssim_diffuse": value["ssim_diffuse"]}, QUALITY)
        assert (mine.setting.iloc[0], mine.bound.iloc[0]) == (pick.setting, pick.bound)
        assert value["equal_quality_speedup"] == pytest.approx(pick.cost / value["ms_per_frame"])


def test_equal_quality_writes_a_deployment_row_per_network_and_material(evaluated):
    deployment = evaluated["deployment"]
    # Two variants, each float32 and int8, each diffuse and glossy.
    assert len(deployment) == 2 * 2 * 2
    assert deployment.network.is_unique


def _image(path) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(path).convert("RGB"), np.float32)


def test_the_noise_floor_compares_two_16_direction_samples_with_the_64_direction_reference(
    evaluated, head, prt_params
):
    out = head / "noise_floor.csv"
    inputs = {"seq": head / "seq.npz", "reference": head / "test", "light": head / "sky_sh.csv"}
    params = prt_params("prt_noise_floor", object="head")
    jobs.prt_noise_floor(inputs, {"csv": out}, params, 1)
    value = io.read_csv(out).set_index("metric")["value"]
    # Two independent 16-direction estimates differ from each other and from the reference,
    # but far less than unrelated images: SSIM in (0.3, 1), L1 positive.
    for metric in ("ssim_sample_vs_sample", "ssim_sample_vs_reference"):
        assert 0.3 < value[metric] < 1.0
    assert (value[[m for m in value.index if m.startswith("l1_")]] > 0).all()


def test_the_data_summary_counts_each_splits_frames_and_copies_the_noise_floor(
    head, tmp_path, prt_config, prt_params
):
    noise = pd.DataFrame(
        {"method": "prt", "object": "head", "model": "gt", "split": "test"}
        | {"metric": ["ssim_sample_vs_sample"] * 2, "frame": [0, 1], "value": [0.9, 0.8]}
    )
    io.write_csv(tmp_path / "noise_floor.csv", noise)
    _transfer(prt_params, head, "sky_sh.csv", "summary_test", 1)
    manifest = head / "summary_test.csv"
    outputs = {"data": tmp_path / "data.csv", "noise": tmp_path / "noise.csv"}
    inputs = {
        "gim": [head / "gim.csv"],
        "manifests": [manifest],
        "noise": [tmp_path / "noise_floor.csv"],
    }
    jobs.prt_summary(inputs, outputs, {}, 1)
    data = io.read_csv(outputs["data"])
    gt = data[data.model == "ray-traced ground truth"].set_index("metric")["value"]
    assert gt["frames"] == prt_config["prt"]["frames"]["test"]
    assert gt["directions"] == TEST_DIRECTIONS
    pd.testing.assert_frame_equal(io.read_csv(outputs["noise"]), noise.drop(columns="frame"))


def test_the_relit_frame_blends_two_probes_and_scores_each_blend(
    evaluated, trained, head, prt_params
):
    probe = {"exr": head / "dusk.exr", "sh": head / "dusk_sh.csv"}
    data_jobs.prt_probe({}, probe, prt_params("prt_probe", probe="sunset"), 1)
    _, files = trained
    inputs = {
        "seq": head / "seq.npz",
        "test_dir": head / "test",
        "test_manifest": head / "test_manifest.csv",
    }
    inputs |= {"deepprt": files["shadowing", "diffuse"]["checkpoint"]}
    inputs |= {"onnx": files["shadowing", "diffuse"]["onnx"]}
    inputs |= {"probes": [head / "sky_sh.csv", head / "dusk_sh.csv"]}
    outputs = {"csv": head / "relight.csv", "figure": head / "relight.png"}
    params = prt_params("prt_relight", object="head")
    jobs.prt_relight(inputs, outputs, params, 1)
    table = io.read_csv(outputs["csv"])
    assert table.value.between(-1, 1).all() and len(table) >= 2
    assert _image(outputs["figure"]).std() > 0
    with pytest.raises(ValueError, match="dynamic lighting needs two light probes"):
        jobs.prt_relight({**inputs, "probes": inputs["probes"][:1]}, outputs, params, 1)


def test_the_frames_and_probes_figures_draw_the_data(head, prt_params):
    _transfer(prt_params, head, "sky_sh.csv", "figure_test", 1)
    jobs.prt_figure(
        {"frames": head / "figure_test", "light": head / "sky_sh.csv"},
        {"png": head / "frames.png"},
        prt_params("prt_figure", object="head"),
        1,
    )
    jobs.prt_probes_figure(
        {"exrs": [head / "sky.exr"], "sh": [head / "sky_sh.csv"]},
        {"png": head / "probes.png"},
        prt_params("prt_probes_figure"),
        1,
    )
    for png in ("frames.png", "probes.png"):
        assert _image(head / png).std() > 1  # drawn, not blank


def test_the_ray_tracing_benchmark_times_the_stage_and_embree(head, tmp_path, prt_params):
    out = tmp_path / "benchmark.csv"
    params = prt_params("prt_benchmark")
    data_jobs.prt_benchmark(
        {"seq": head / "seq.npz", "light": head / "sky_sh.csv"}, {"csv": out}, params, 1
    )
    value = io.read_csv(out).set_index("metric")["value"]
    assert value["stage_rays_per_s"] > 0 and value["embree_rays_per_s"] > 0
    fraction = value["stage_rays_per_s"] / value["embree_rays_per_s"]
    assert value["stage_fraction_of_embree"] == pytest.approx(fraction)
    assert value["target_met"] == float(fraction >= value["target_fraction"])
    assert value["seconds_per_frame"] > 0


def test_the_experiment_scores_each_variants_diffuse_network_and_momoprt_along_the_path(
    evaluated, trained, head, prt_config, prt_params
):
    _, files = trained
    params = prt_params("prt_experiment", object="head_excluded")
    variants = params["variants"]
    inputs = {"seq": head / "seq.npz", "light": head / "sky_sh.csv"}
    inputs |= {"test_dir": head / "test", "test_manifest": head / "test_manifest.csv"}
    inputs |= {input_name("pt", v, "diffuse"): files[v, "diffuse"]["checkpoint"] for v in variants}
    inputs |= {input_name("onnx", v, "diffuse"): files[v, "diffuse"]["onnx"] for v in variants}
    inputs |= {"momoprt": head / "momoprt_diffuse.npz"}
    outputs = {"csv": head / "experiment.csv", "figure": head / "experiment.png"}
    outputs |= {"deployment": head / "experiment_deployment.csv"}
    jobs.prt_experiment(inputs, outputs, params, 1)
    table = io.read_csv(outputs["csv"])
    assert set(table.model) == {"DeepPRT", "DeepPRT shadowing", "MoMoPRT"}
    frames_ = prt_config["prt"]["frames"]["test"]
    assert table.groupby(["model", "metric"]).size().eq(frames_).all()  # every test frame
    deployment = io.read_csv(outputs["deployment"])
    assert sorted(deployment.network.str.contains("shadowing")) == [False, True]
    assert _image(outputs["figure"]).std() > 1


@pytest.fixture(scope="module")
def model_summary(evaluated, trained, head, tmp_path_factory, prt_params):
    """The model summary's and the targets' jobs run on the head's evaluation, its
    held-out experiment and an unseen-deformation benchmark of one frame: (the files
    of the summary's outputs, the targets' table)."""
    tmp_path = tmp_path_factory.mktemp("model_summary")
    _, files = trained
    stem = head / "variants" / "paper_glossy"  # trained by the evaluation fixture
    files = {**files, ("paper", "glossy"): {"checkpoint": f"{stem}.pt", "onnx": f"{stem}.onnx"}}
    files["paper", "glossy"] |= {"int8": f"{stem}_int8.onnx", "loss": f"{stem}_loss.csv"}
    params = prt_params("prt_model_summary") | {"objects": ["head"]}
    variants = params["variants"]
    pairs = [(v, m) for v in variants for m in ("diffuse", "glossy")]
    momoprt = {input_name("momoprt", m): head / f"momoprt_{m}.npz" for m in ("diffuse", "glossy")}
    light = head / "sky_sh.csv"
    unseen = {"csv": tmp_path / "unseen.csv", "figure": tmp_path / "unseen.png"}
    unseen_inputs = {"gim": head / "gim.npz", "seq": head / "seq.npz", "light": light, **momoprt}
    unseen_inputs |= {input_name("pt", *p): files[p]["checkpoint"] for p in pairs}
    unseen_inputs |= {input_name("onnx", *p): files[p]["onnx"] for p in pairs}
    unseen_params = prt_params("prt_unseen", object="head")
    unseen_params |= {"unseen_strengths": [1.0], "reference_directions": 16}
    jobs.prt_unseen(unseen_inputs, unseen, unseen_params, 1)
    experiment = {"csv": tmp_path / "experiment.csv", "figure": tmp_path / "experiment.png"}
    experiment["deployment"] = tmp_path / "experiment_deployment.csv"
    inputs = {"seq": head / "seq.npz", "light": light, "momoprt": head / "momoprt_diffuse.npz"}
    inputs |= {"test_dir": head / "test", "test_manifest": head / "test_manifest.csv"}
    inputs |= {input_name("pt", v, "diffuse"): files[v, "diffuse"]["checkpoint"] for v in variants}
    inputs |= {input_name("onnx", v, "diffuse"): files[v, "diffuse"]["onnx"] for v in variants}
    jobs.prt_experiment(inputs, experiment, prt_params("prt_experiment", object="head_excluded"), 1)
    summary_inputs = {
        "metrics": [head / "metrics.csv"],
        "equal_quality": [head / "equal_quality.csv"],
        "deployment": [head / "deployment.csv", experiment["deployment"]],
    }
    for kind, name in (("pt", "checkpoint"), ("onnx", "onnx"), ("loss.csv", "loss")):
        summary_inputs |= {input_name(kind, "head", *p): files[p][name] for p in pairs}
    for m in ("diffuse", "glossy"):
        summary_inputs[input_name("shipped", "head", m)] = files["shadowing", m]["onnx"]
        summary_inputs[input_name("shipped_int8", "head", m)] = files["shadowing", m]["int8"]
    for split in ("train", "val", "test"):
        summary_inputs[input_name("frames", "head", split)] = head / split
    names = ("metrics", "equal_quality", "deployment", "compression")
    outputs = {name: tmp_path / f"summary_{name}.csv" for name in names}
    outputs |= {"loss": tmp_path / "loss.png", "equal_quality_figure": tmp_path / "eq.png"}
    jobs.prt_model_summary(summary_inputs, outputs, params, 1)
    target_inputs = {k: outputs[k] for k in ("metrics", "equal_quality")}
    target_inputs |= {"experiments": [experiment["csv"]], "unseen": unseen["csv"]}
    targets = {"targets": tmp_path / "targets.csv"}
    jobs.prt_targets(target_inputs, targets, prt_params("prt_targets"), 1)
    return outputs, io.read_csv(targets["targets"])


def test_the_model_summary_gathers_every_objects_results(model_summary, evaluated, prt_params):
    outputs, _ = model_summary
    variants = prt_params("prt_model_summary")["variants"]
    pd.testing.assert_frame_equal(io.read_csv(outputs["metrics"]), evaluated["metrics"])
    equal = io.read_csv(outputs["equal_quality"])
    pd.testing.assert_frame_equal(equal, evaluated["equal_quality"])
    deployment = io.read_csv(outputs["deployment"])
    assert len(deployment) == len(evaluated["deployment"]) + len(variants)  # + the experiment's
    compression = io.read_csv(outputs["compression"])
    shipped = compression[compression.model.str.endswith("(shipped)")]
    assert set(shipped.model) == {
        f"DeepPRT shadowing{kind} {m} (shipped)"
        for kind in ("", " int8")
        for m in ("diffuse", "glossy")
    }
    for png in ("loss", "equal_quality_figure"):
        assert _image(outputs[png]).std() > 1


def test_the_targets_are_the_shipped_variants_of_every_object_experiment_and_benchmark(
    model_summary,
):
    outputs, targets = model_summary
    assert set(targets.subject) >= {"head", "head_excluded"}
    assert targets.met.isin([True, False]).all()
    assert targets.check.str.contains("DeepPRT shadowing").all()
    speed = targets[targets.check.str.contains("faster than the cheapest ray-traced transfer")]
    assert len(speed) == 2  # the shipped variant's float32 and int8 graphs
    # Each equal-quality target states the speed-up of its graph's row in the summary.
    equal = io.read_csv(outputs["equal_quality"])
    ratios = equal[equal.metric == "equal_quality_speedup"].set_index("model")["value"]
    for row in speed.itertuples():
        model = row.check.split(" at least ")[0]
        assert row.measured == pytest.approx(ratios[model])
