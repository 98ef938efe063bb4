import numpy as np
import pytest
import torch

from neurender.prt.frames import Split
from neurender.prt.model import (
    DeepPRT,
    Normalisation,
    TransferNetwork,
    build_network,
    export_deepprt,
    raw_inputs,
)
from neurender.prt.momoprt import MoMoPRT, fit_momoprt
from neurender.prt.training import train_deepprt


def _split(params, rng, n=4, k=16, affine=None):
    f = len(params)
    positions = rng.normal(size=(f, n, n, 3)).astype(np.float32)
    normals = rng.normal(size=(f, n, n, 3)).astype(np.float32)
    w, b = affine
    diffuse = (params @ w + b).reshape(f, n, n, k)
    glossy = rng.normal(size=(f, n, n, 3, k)).astype(np.float32)
    return Split(positions, normals, diffuse, glossy, params)


def test_momoprt_recovers_an_affine_map_from_blendshape_weights():
    rng = np.random.default_rng(0)
    w, b = rng.normal(size=(3, 4 * 4 * 16)), rng.normal(size=4 * 4 * 16)
    train = _split(rng.uniform(0, 1, (30, 3)), rng, affine=(w, b))
    val = _split(rng.uniform(0, 1, (5, 3)), rng, affine=(w, b))
    test = _split(rng.uniform(1, 1.5, (5, 3)), rng, affine=(w, b))  # extrapolation
    model = fit_momoprt(train, val, "diffuse", use_params=True, pca_components=4, ridges=[0.0, 1.0])
    assert model.ridge == 0.0  # the exact fit wins on validation
    np.testing.assert_allclose(model.predict(test), test.targets("diffuse"), atol=1e-3)


def test_momoprt_pca_path_and_save_load(tmp_path):
    rng = np.random.default_rng(1)
    w, b = rng.normal(size=(2, 4 * 4 * 16)), rng.normal(size=4 * 4 * 16)
    train = _split(rng.uniform(0, 1, (12, 2)), rng, affine=(w, b))
    model = fit_momoprt(train, train, "glossy", use_params=False, pca_components=3, ridges=[1e-3])
    assert model.basis.shape == (3, 4 * 4 * 3)
    model.save(tmp_path / "m.npz")
    again = MoMoPRT.load(tmp_path / "m.npz")
    np.testing.assert_allclose(again.predict(train), model.predict(train), rtol=1e-6)
    assert again.predict(train).shape == (12, 48, 4, 4)


@pytest.mark.parametrize("residual", [False, True])
def test_normalisation_round_trip_and_range(residual):
    rng = np.random.default_rng(2)
    w, b = rng.normal(size=(2, 4 * 4 * 16)), rng.normal(size=4 * 4 * 16)
    split = _split(rng.uniform(0, 1, (6, 2)), rng, affine=(w, b))
    norm = Normalisation.fit(split, "diffuse", residual=residual)
    t = split.targets("diffuse")
    enc = norm.encode(t)
    assert enc.min() >= 0.1 / 1.2 - 1e-6 and enc.max() <= 1.1 / 1.2 + 1e-6  # 10% margin each side
    np.testing.assert_allclose(norm.decode(enc), t, atol=1e-5)
    x = norm.inputs(split)
    assert x.shape == (6, 6, 4, 4) and np.abs(x[:, :3]).max() <= 1.0 + 1e-6


def test_residual_targets_put_the_mean_image_at_one_half():
    rng = np.random.default_rng(3)
    w, b = rng.normal(size=(2, 4 * 4 * 16)), rng.normal(size=4 * 4 * 16)
    split = _split(rng.uniform(0, 1, (8, 2)), rng, affine=(w, b))
    norm = Normalisation.fit(split, "diffuse", residual=True)
    np.testing.assert_allclose(norm.encode(split.targets("diffuse")).mean(0), 0.5, atol=1e-5)


@pytest.mark.parametrize("residual", [False, True])
def test_transfer_network_decodes_the_network_of_normalised_inputs(residual):
    """The shipped graph equals the numpy normalisation, network and decoding in sequence."""
    rng = np.random.default_rng(4)
    w, b = rng.normal(size=(2, 4 * 4 * 16)), rng.normal(size=4 * 4 * 16)
    split = _split(rng.uniform(0, 1, (3, 2)), rng, affine=(w, b))
    split.positions = split.positions * 5 + 2  # away from the unit box the normalisation undoes
    norm = Normalisation.fit(split, "diffuse", residual=residual)
    torch.manual_seed(0)
    network = build_network(16, [4, 8], 1).eval()
    with torch.no_grad():
        expected = norm.decode(network(torch.from_numpy(norm.inputs(split))).numpy())
        got = TransferNetwork(network, norm)(torch.from_numpy(raw_inputs(split))).numpy()
    np.testing.assert_allclose(got, expected, rtol=1e-5, atol=1e-5)


def test_trained_deepprt_exports_and_both_engines_agree(tmp_path, tensorboard_steps, prt_params):
    rng = np.random.default_rng(5)
    w, b = rng.normal(size=(2, 4 * 4 * 16)), rng.normal(size=4 * 4 * 16)
    train = _split(rng.uniform(0, 1, (6, 2)), rng, affine=(w, b))
    val = _split(rng.uniform(0, 1, (3, 2)), rng, affine=(w, b))
    cfg = prt_params("prt_train", material="glossy", variant="paper")
    checkpoint, onnx_file = tmp_path / "net.pt", tmp_path / "net.onnx"
    board = tmp_path / "tensorboard" / "run.json"
    loss_csv = str(tmp_path / "loss.csv")
    train_deepprt(train, val, "glossy", cfg, 1, str(checkpoint), loss_csv, tensorboard=str(board))
    logged = tensorboard_steps(board.parent)
    assert logged["val/loss"] == logged["previews/prediction"] == logged["lr"] == [1]
    export_deepprt(checkpoint, val, onnx_file)
    net = DeepPRT(checkpoint, onnx_file, device="cpu")
    assert net.engine == "onnxruntime" and set(net.engines) == {"onnxruntime", "pytorch"}
    shipped = net.predict(val, batch=2)
    assert shipped.shape == (3, 48, 4, 4)
    np.testing.assert_allclose(shipped, net.predict(val, engine="pytorch"), atol=1e-5)
    assert DeepPRT(checkpoint, device="cpu").engine == "pytorch"  # no file: PyTorch
