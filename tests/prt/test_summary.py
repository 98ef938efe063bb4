import numpy as np
import pandas as pd
import pytest
import torch

from neurender import train
from neurender.nn.unet import count_parameters
from neurender.prt.frames import Split
from neurender.prt.model import Normalisation, build_network, load_transfer_module
from neurender.prt.summary import compression_rows, shipped_rows, target_frame
from neurender.prt.training import train_deepprt
from neurender.tables import threshold, tidy_rows


def _split(frames, rng, n=4, k=16):
    positions = rng.normal(size=(frames, n, n, 3)).astype(np.float32)
    normals = rng.normal(size=(frames, n, n, 3)).astype(np.float32)
    diffuse = rng.normal(size=(frames, n, n, k)).astype(np.float32)
    glossy = rng.normal(size=(frames, n, n, 3, k)).astype(np.float32)
    return Split(positions, normals, diffuse, glossy, np.zeros((frames, 1), np.float32))


@pytest.fixture(scope="module")
def trained(tmp_path_factory, prt_params):
    """Checkpoints of both materials of one object, as the training rule writes them."""
    folder = tmp_path_factory.mktemp("deepprt")
    rng = np.random.default_rng(0)
    splits = _split(4, rng), _split(2, rng)
    paths = {}
    for material in ("diffuse", "glossy"):
        paths[material] = folder / f"deepprt_{material}.pt"
        cfg = prt_params("prt_train", material=material, variant="paper")
        train_deepprt(*splits, material, cfg, 1, str(paths[material]), str(folder / "l.csv"))
    return folder, paths, splits


def test_a_trained_checkpoint_loads_with_weights_only_and_keeps_the_normalisation(trained):
    _, paths, (train_split, _) = trained
    state = torch.load(paths["glossy"], weights_only=True)  # tensors and plain types only
    stored = Normalisation(**{k: np.asarray(v) for k, v in state["extra"]["normalisation"].items()})
    fitted = Normalisation.fit(train_split, "glossy", residual=True)
    for name, value in vars(fitted).items():
        assert getattr(stored, name).dtype == value.dtype
        np.testing.assert_array_equal(getattr(stored, name), value)
    np.testing.assert_array_equal(
        load_transfer_module(paths["glossy"]).t_offset[0].numpy(), fitted.t_offset
    )


def test_compression_rows_read_the_parameters_from_the_checkpoints(trained, prt_params):
    folder, paths, _ = trained
    dirs = [folder / s for s in ("train", "val", "test")]
    for d, count in zip(dirs, (3, 2, 4), strict=True):
        d.mkdir(exist_ok=True)
        for i in range(count):
            (d / f"{i:03d}.exr").write_bytes(b"x" * 10)
    onnx = {}
    for material in paths:
        onnx[("obj", "DeepPRT", material)] = folder / f"{material}.onnx"
        onnx[("obj", "DeepPRT", material)].write_bytes(b"y" * (7 if material == "diffuse" else 9))
    checkpoints = {("obj", "DeepPRT", m): p for m, p in paths.items()}
    table = compression_rows(["obj"], checkpoints, onnx, {"obj": dirs}, n=4, n_bands=4)
    for material, m in (("diffuse", 16), ("glossy", 48)):
        rows = table[(table.dataset == "obj") & (table.model == f"DeepPRT {material}")]
        value = dict(zip(rows.metric, rows.value, strict=True))
        cfg = prt_params("prt_train", material=material, variant="paper")
        params = count_parameters(build_network(m, cfg["widths"], cfg["blocks"]))
        assert value["parameters"] == params
        assert value["compression_ratio"] == pytest.approx(5 * 4 * 4 * m / params)  # train + val
        assert value["network_file_bytes"] == (7 if material == "diffuse" else 9)
    assert value["classic_store_float32_bytes"] == 5 * 4 * 4 * 48 * 4


def test_compression_rows_refuse_an_old_checkpoint_holding_numpy_arrays_naming_it(
    trained, tmp_path
):
    _, paths, _ = trained
    state = torch.load(paths["diffuse"], weights_only=True)
    state["extra"]["normalisation"] = {
        k: v.numpy() for k, v in state["extra"]["normalisation"].items()
    }
    old = tmp_path / "numpy.pt"
    torch.save(state, old)  # numpy arrays: unpickled by calling numpy's reconstructors
    with pytest.raises(OSError, match=f"refusing to load checkpoint {old}"):
        compression_rows(
            ["obj"], {("obj", "DeepPRT", "diffuse"): old}, {}, {"obj": [tmp_path] * 3}, 4, 4
        )
    assert train.load_checkpoint(paths["diffuse"])["extra"]["material"] == "diffuse"


def test_compression_rows_name_each_variant(trained, tmp_path):
    """Two variants' checkpoints of one object give two sets of rows, each its own."""
    folder, paths, _ = trained
    dirs = [tmp_path / s for s in ("train", "val", "test")]
    for d in dirs:
        d.mkdir()
        (d / "0.exr").write_bytes(b"x")
    checkpoints, onnx = {}, {}
    for model, size in (("DeepPRT", 3), ("DeepPRT shadowing", 5)):
        checkpoints["obj", model, "diffuse"] = paths["diffuse"]
        onnx["obj", model, "diffuse"] = tmp_path / f"{size}.onnx"
        onnx["obj", model, "diffuse"].write_bytes(b"y" * size)
    table = compression_rows(["obj"], checkpoints, onnx, {"obj": dirs}, n=4, n_bands=4)
    sizes = table[table.metric == "network_file_bytes"].set_index("model").value
    assert sizes.to_dict() == {"DeepPRT diffuse": 3, "DeepPRT shadowing diffuse": 5}
    shipped = shipped_rows(
        {("obj", "diffuse"): onnx["obj", "DeepPRT shadowing", "diffuse"]}, "DeepPRT shadowing"
    )
    assert shipped.model.tolist() == ["DeepPRT shadowing diffuse (shipped)"]
    assert shipped.value.tolist() == [5]


def _metrics(paper_l1: float, shadowing_l1: float) -> pd.DataFrame:
    """One object's aggregated rows: the shadowing variant above MoMoPRT in SSIM, the
    paper's form below it; relative L1 of radiance of both."""
    rows = []
    for model, ssim, l1 in (
        ("DeepPRT", 0.90, paper_l1),
        ("DeepPRT shadowing", 0.99, shadowing_l1),
        ("MoMoPRT", 0.95, 0.2),
    ):
        for material in ("diffuse", "glossy"):
            values = {f"ssim_{material}": ssim, f"rel_l1_radiance_{material}": l1}
            rows += tidy_rows("prt", "obj", model, "test", values)
    return pd.DataFrame(rows)


def _equal(speedups: dict[str, float]) -> pd.DataFrame:
    """Equal-quality rows of networks (model -> speed-up) of a pick inside the sweep."""
    rows = []
    for model, speedup in speedups.items():
        rows += tidy_rows(
            "prt",
            "obj",
            model,
            "equal quality",
            {"equal_quality_speedup": speedup},
            setting="64 directions",
            bound="within the sweep",
        )
    return pd.DataFrame(rows)


#: Every network at 30x.
EQUAL = _equal({m: 30.0 for m in ("DeepPRT", "DeepPRT shadowing", "MoMoPRT")})


def test_targets_are_those_of_the_shipped_variant():
    table = _metrics(0.10, 0.04)
    shipped = target_frame(table, EQUAL, [], "DeepPRT shadowing").set_index("check")
    above = "DeepPRT shadowing ssim_diffuse on test above MoMoPRT's (0.9500)"
    assert shipped.loc[above, "measured"] == 0.99 and shipped.loc[above, "met"]
    paper = target_frame(table, EQUAL, [], "DeepPRT").set_index("check")
    above = "DeepPRT ssim_diffuse on test above MoMoPRT's (0.9500)"
    assert paper.loc[above, "measured"] == 0.90 and not paper.loc[above, "met"]
    assert not any("shadowing" in c for c in paper.index)


@pytest.mark.parametrize(("shadowing_l1", "met"), [(0.05, True), (0.051, False)])
def test_the_shipped_variant_needs_half_the_paper_forms_radiance_error(shadowing_l1, met):
    assert threshold("prt", "rel_l1_vs_paper") == 0.5
    found = target_frame(_metrics(0.10, shadowing_l1), EQUAL, [], "DeepPRT shadowing")
    rows = found[found.check.str.contains("rel_l1_radiance")]
    assert len(rows) == 2  # diffuse and glossy
    assert rows.measured.tolist() == [shadowing_l1] * 2 and rows.met.tolist() == [met] * 2
    assert "<= 0.5 x DeepPRT's (0.1000)" in rows.check.iloc[0]


@pytest.mark.parametrize(("int8_l1", "met"), [(0.044, True), (0.0441, False)])
def test_the_int8_graph_keeps_its_radiance_error_within_the_ratio_of_the_float32_graphs(
    int8_l1, met
):
    table = _metrics(0.10, 0.04)
    for material in ("diffuse", "glossy"):
        values = {f"rel_l1_radiance_{material}": int8_l1}
        rows = tidy_rows("prt", "obj", "DeepPRT shadowing int8", "test", values)
        table = pd.concat([table, pd.DataFrame(rows)])
    assert threshold("prt", "int8_rel_l1_ratio") == 1.1
    equal = pd.concat([EQUAL, _equal({"DeepPRT shadowing int8": 25.0})])
    found = target_frame(table, equal, [], "DeepPRT shadowing")
    int8 = found[found.check.str.startswith("DeepPRT shadowing int8 rel_l1_radiance")]
    assert len(int8) == 2 and int8.met.tolist() == [met] * 2
    assert "<= 1.1 x the float32 graph's (0.0400)" in int8.check.iloc[0]
    speed = found[found.check.str.startswith("DeepPRT shadowing int8 at least 20x faster")]
    assert speed.measured.tolist() == [25.0] and speed.met.tolist() == [True]


def test_no_int8_targets_without_an_int8_graph():
    found = target_frame(_metrics(0.10, 0.04), EQUAL, [], "DeepPRT shadowing")
    assert not found.check.str.contains("int8").any()


@pytest.mark.parametrize(("floor", "noted"), [(0.049, False), (0.051, True)])
def test_a_radiance_target_below_the_references_own_noise_says_so(floor, noted):
    table = _metrics(0.10, 0.04)
    for model, value in (("ground truth 256 dirs", 0.2), ("ground truth 1024 dirs", floor)):
        rows = tidy_rows("prt", "obj", model, "test", {"rel_l1_radiance_glossy": value})
        table = pd.concat([table, pd.DataFrame(rows)])
    found = target_frame(table, EQUAL, [], "DeepPRT shadowing")
    glossy = found[found.check.str.contains("rel_l1_radiance_glossy")]
    assert glossy.met.tolist() == [True]  # noted or not, met is the measured comparison
    assert glossy.check.str.contains(f"below the {floor:.4f} of an independent").tolist() == [noted]
    diffuse = found[found.check.str.contains("rel_l1_radiance_diffuse")]
    assert not diffuse.check.str.contains("independent").any()  # no floor row for diffuse


def test_no_radiance_target_without_the_paper_form():
    table = _metrics(0.10, 0.04)
    alone = table[table.model != "DeepPRT"]
    found = target_frame(alone, EQUAL, [], "DeepPRT shadowing")
    assert not found.check.str.contains("rel_l1_radiance").any()


def test_the_fig6_targets_are_those_of_the_shipped_variant():
    """Past the middle of the excluded-expression path the shadowing variant is below
    MoMoPRT (not before it: that point does not count) and 2x below at the far end; the
    paper's form is above MoMoPRT there."""
    rows = []
    points = [(0.0, 1.0, 0.5, 0.2), (0.75, 1.0, 0.5, 0.8), (1.0, 3.0, 1.0, 2.0)]
    for x, paper, shadowing, momoprt in points:
        for model, value in (("DeepPRT", paper), ("DeepPRT shadowing", shadowing)):
            rows += tidy_rows("prt", "head_excluded", model, "test", {"l2rgb_diffuse": value}, x=x)
        rows += tidy_rows(
            "prt", "head_excluded", "MoMoPRT", "test", {"l2rgb_diffuse": momoprt}, x=x
        )
    table = pd.DataFrame(rows)
    shipped = target_frame(
        pd.DataFrame(columns=table.columns), EQUAL.iloc[:0], [table], "DeepPRT shadowing"
    )
    far = shipped.set_index("check").loc["MoMoPRT / DeepPRT shadowing L2-RGB at the far end >= 1.5"]
    assert far.measured == 2.0 and far.met
    assert shipped.met.all() and len(shipped) == 2
    paper = target_frame(pd.DataFrame(columns=table.columns), EQUAL.iloc[:0], [table], "DeepPRT")
    assert paper.set_index("check").loc[
        "MoMoPRT / DeepPRT L2-RGB at the far end >= 1.5"
    ].measured == (pytest.approx(2 / 3))
    assert not paper.met.any()


@pytest.mark.parametrize(("inside", "met"), [(0.9, True), (1.1, False)])
def test_the_linear_blend_target_counts_only_the_extrapolated_points(inside, met):
    """Inside the training range [0, 1] MoMoPRT may win; outside it the variant must."""
    rows = []
    for x, shadowing in ((-0.25, inside), (0.5, 5.0), (1.25, 0.5)):
        for model, value in (("DeepPRT shadowing", shadowing), ("MoMoPRT", 1.0)):
            rows += tidy_rows("prt", "head_linear", model, "test", {"l2rgb_diffuse": value}, x=x)
    table = pd.DataFrame(rows)
    found = target_frame(
        pd.DataFrame(columns=table.columns), EQUAL.iloc[:0], [table], "DeepPRT shadowing"
    )
    row = found.set_index("check").loc[
        "DeepPRT shadowing L2-RGB below MoMoPRT's over the whole extrapolated range "
        "(x < 0 or x > 1)"
    ]
    assert row.met == met and row.measured == (1.0 if met else 0.5)
