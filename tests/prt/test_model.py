import numpy as np
import pytest

from neurender.prt.model import MoMoPRT, Normalisation, Split, fit_momoprt


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
