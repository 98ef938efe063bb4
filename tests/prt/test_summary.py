import numpy as np
import pytest
import torch

from neurender import train
from neurender.nn.unet import count_parameters
from neurender.prt.frames import Split
from neurender.prt.model import DeepPRT, Normalisation, build_network
from neurender.prt.summary import compression_rows
from neurender.prt.training import train_deepprt

CFG = {"seed": 0, "widths": [4, 8], "blocks": 1, "epochs": 1, "batch_size": 2, "lr": 1e-3}
CFG |= {"residual_targets": True, "device": "cpu", "lr_schedule": "cosine"}


def _split(frames, rng, n=4, k=16):
    positions = rng.normal(size=(frames, n, n, 3)).astype(np.float32)
    normals = rng.normal(size=(frames, n, n, 3)).astype(np.float32)
    diffuse = rng.normal(size=(frames, n, n, k)).astype(np.float32)
    glossy = rng.normal(size=(frames, n, n, 3, k)).astype(np.float32)
    return Split(positions, normals, diffuse, glossy, np.zeros((frames, 1), np.float32))


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """Checkpoints of both materials of one object, as the training rule writes them."""
    folder = tmp_path_factory.mktemp("deepprt")
    rng = np.random.default_rng(0)
    splits = _split(4, rng), _split(2, rng)
    paths = {}
    for material in ("diffuse", "glossy"):
        paths[material] = folder / f"deepprt_{material}.pt"
        train_deepprt(*splits, material, CFG, 1, str(paths[material]), str(folder / "l.csv"))
    return folder, paths, splits


def test_a_trained_checkpoint_loads_with_weights_only_and_keeps_the_normalisation(trained):
    _, paths, (train_split, _) = trained
    state = torch.load(paths["glossy"], weights_only=True)  # tensors and plain types only
    stored = Normalisation(**{k: np.asarray(v) for k, v in state["extra"]["normalisation"].items()})
    fitted = Normalisation.fit(train_split, "glossy", residual=True)
    for name, value in vars(fitted).items():
        assert getattr(stored, name).dtype == value.dtype
        np.testing.assert_array_equal(getattr(stored, name), value)
    # The loaded graph's buffer (channels-last copies keep the values).
    loaded = DeepPRT(paths["glossy"], device="cpu").module.t_offset.numpy()
    np.testing.assert_array_equal(loaded[0], fitted.t_offset)


def test_compression_rows_read_the_parameters_from_the_checkpoints(trained):
    folder, paths, _ = trained
    dirs = [folder / s for s in ("train", "val", "test")]
    for d, count in zip(dirs, (3, 2, 4), strict=True):
        d.mkdir(exist_ok=True)
        for i in range(count):
            (d / f"{i:03d}.exr").write_bytes(b"x" * 10)
    onnx = {}
    for material in paths:
        onnx[("obj", material)] = folder / f"{material}.onnx"
        onnx[("obj", material)].write_bytes(b"y" * (7 if material == "diffuse" else 9))
    checkpoints = {("obj", m): p for m, p in paths.items()}
    table = compression_rows(["obj"], checkpoints, onnx, {"obj": dirs}, n=4, n_bands=4)
    for material, m in (("diffuse", 16), ("glossy", 48)):
        rows = table[(table.dataset == "obj") & (table.model == f"DeepPRT {material}")]
        value = dict(zip(rows.metric, rows.value, strict=True))
        params = count_parameters(build_network(m, CFG["widths"], CFG["blocks"]))
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
        compression_rows(["obj"], {("obj", "diffuse"): old}, {}, {"obj": [tmp_path] * 3}, 4, 4)
    assert train.load_checkpoint(paths["diffuse"])["extra"]["material"] == "diffuse"
