import torch

from neurender import io
from neurender.metaballs import GAN_VARIANTS, VARIANTS, inputs, jobs, model, scenes
from neurender.metaballs.renderer import MetaballRenderer, load_renderers


def _train_params(variant: str) -> dict:
    params = {"seed": 1, "device": "cpu", "width": 32, "variant": variant, "ngf": 4}
    params |= {"l1_weight": 100.0, "flips": True, "epochs": 1, "batch_size": 4, "lr": 1e-3}
    params |= {"lr_schedule": "cosine"}
    gan = variant in GAN_VARIANTS
    return params | ({"ndf": 4, "gan_weight": 1.0} if gan else {"gan_weight": 0.0})


def test_every_variant_trains_and_renders_g_buffers(
    tmp_path, write_split, split_files, tensorboard_steps
):
    write_split("train", 4)
    write_split("val", 2)
    files = split_files
    scene = scenes.sample_scene(3, (1.0, 2.0), torch.Generator().manual_seed(0)).to(torch.float32)
    for variant in VARIANTS:
        outputs = {
            "checkpoint": str(tmp_path / f"{variant}.pt"),
            "loss": str(tmp_path / f"{variant}.csv"),
            "tensorboard": str(tmp_path / "tensorboard" / variant / "run.json"),
        }
        jobs.metaballs_train(files, outputs, _train_params(variant), 1)
        logged = tensorboard_steps(tmp_path / "tensorboard" / variant)
        assert logged["train/l1"] == logged["previews/ssim"] == logged["previews/error"] == [1]
        loss = io.read_csv(outputs["loss"], ["epoch", "split", "metric", "value"])
        assert {("train", "l1"), ("val", "l1")} <= set(zip(loss.split, loss.metric, strict=True))
        assert (("train", "gan") in set(zip(loss.split, loss.metric, strict=True))) == (
            variant in GAN_VARIANTS
        )
        renderer = MetaballRenderer(outputs["checkpoint"], "cpu")
        assert renderer.image_statistics == (variant in GAN_VARIANTS)
        x = renderer.inputs(scene)
        assert x.shape == (model.input_channels(variant), 32, 32)
        out = renderer(torch.stack([x, x]))
        assert out.shape == (2, 7, 32, 32) and 0 <= out.min() and out.max() <= 1
        torch.testing.assert_close(out[0], out[1])  # images never mix in a batch
    # Barely trained, the residual model still renders about its prior.
    prior = inputs.inflated_spheres(scene, 32).stack()
    assert (out[0] - prior).abs().mean() < 0.2
    # Each renderer is named by the variant its checkpoint was trained as, in the files' order.
    order = list(reversed(VARIANTS))
    loaded = load_renderers([str(tmp_path / f"{v}.pt") for v in order], "cpu", 1)
    assert list(loaded) == order
    assert all(r.variant == name for name, r in loaded.items())
