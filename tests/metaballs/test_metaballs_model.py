import pytest
import torch

from neurender.metaballs import data, inputs, model, scenes


def test_residual_generator_starts_at_its_prior():
    torch.manual_seed(0)
    net = model.build_generator(32, 4, "sphere_residual")
    x = torch.rand(2, model.input_channels("sphere_residual"), 32, 32) * 2 - 1
    torch.testing.assert_close(net(x), x[:, -model.OUTPUT_CHANNELS :])
    plain = model.build_generator(32, 4, "pix2pix")
    out = plain(torch.rand(2, model.input_channels("pix2pix"), 32, 32))
    assert out.shape == (2, 7, 32, 32) and out.abs().max() < 1  # tanh


def test_unknown_variant_is_named():
    with pytest.raises(ValueError, match="'gan'.*expected one of"):
        model.input_channels("gan")


def _write_split(tmp_path, split, count):
    cfg = {"seed": 1, "width": 32, "examples": {split: count}, "balls": [2, 4], "radius": [1, 2]}
    data.generate_split(
        split,
        cfg,
        1,
        tmp_path / split,
        tmp_path / f"{split}_manifest.csv",
        tmp_path / f"{split}_balls.csv",
    )
    return cfg


def test_dataset_items_and_mirrorings(tmp_path):
    _write_split(tmp_path, "train", 2)
    args = (tmp_path / "train", tmp_path / "train_manifest.csv", tmp_path / "train_balls.csv")
    plain = model.ABDataset(*args, "pix2pix")
    flipped = model.ABDataset(*args, "sphere_residual", flips=True)
    assert len(plain) == 2 and len(flipped) == 8
    x, y = plain[1]
    assert x.shape == (4, 32, 32) and y.shape == (7, 32, 32)
    assert x.min() >= -1 and x.max() <= 1
    x0, y0 = flipped[4]  # example 1, not mirrored
    torch.testing.assert_close(x0[:4], x)
    torch.testing.assert_close(y0, y)
    x1, y1 = flipped[5]  # example 1 mirrored left-right: same depth, mirrored image
    torch.testing.assert_close(y1[3], y[3].flip(-1))
    torch.testing.assert_close(x1[7], x0[7].flip(-1))


def test_training_and_rendering_every_variant(tmp_path):
    cfg = _write_split(tmp_path, "train", 4)
    _write_split(tmp_path, "val", 2)
    files = {
        f"{s}_{k}": str(tmp_path / (s if k == "dir" else f"{s}_{k}.csv"))
        for s in ("train", "val")
        for k in ("dir", "manifest", "balls")
    }
    scene = scenes.sample_scene(3, (1.0, 2.0), torch.Generator().manual_seed(0)).to(torch.float32)
    for variant in model.VARIANTS:
        train_cfg = {
            **cfg,
            "variant": variant,
            "ngf": 4,
            "ndf": 4,
            "gan_weight": 1.0 if variant == "pix2pix" else 0.0,
            "l1_weight": 100.0,
            "flips": True,
            "epochs": 1,
            "batch_size": 4,
            "lr": 1e-3,
            "device": "cpu",
        }
        ckpt = tmp_path / f"{variant}.pt"
        model.train_generator(files, train_cfg, 1, str(ckpt), str(tmp_path / f"{variant}.csv"))
        renderer = model.MetaballRenderer(ckpt, "cpu")
        assert renderer.image_statistics == (variant == "pix2pix")
        x = renderer.inputs(scene)
        assert x.shape == (model.input_channels(variant), 32, 32)
        out = renderer(torch.stack([x, x]))
        assert out.shape == (2, 7, 32, 32) and 0 <= out.min() and out.max() <= 1
        torch.testing.assert_close(out[0], out[1])  # images never mix in a batch
    # Barely trained, the residual model still renders about its prior.
    prior = inputs.inflated_spheres(scene, 32).stack()
    assert (out[0] - prior).abs().mean() < 0.2
