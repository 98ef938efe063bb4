import dataclasses

import pytest
import torch

from neurender.display import reinhard
from neurender.ndr.model import (
    NDRModel,
    architecture,
    inverse_reinhard,
    loss_terms,
    shading_input,
)
from neurender.ndr.variants import VARIANTS
from neurender.nn.ndr import NDRNet
from neurender.nn.unet import count_parameters

SMALL = {"widths": [4, 8], "sh_hidden": 8, "ngf": 4, "width": 32, "shading_residual": True}


def _batch(n: int = 2, width: int = 32) -> dict[str, torch.Tensor]:
    g = torch.Generator().manual_seed(0)

    def r(c: int) -> torch.Tensor:
        return torch.rand(n, c, width, width, generator=g)

    return {
        "N": torch.nn.functional.normalize(r(3) - 0.5, dim=1),
        "R": r(1),
        "D": r(1),
        "A_D": r(3),
        "A_S": r(3),
        "S_D": 3 * r(3),
        "S_S": 2 * r(3),
        "I_D": 3 * r(3),
        "I_S": 2 * r(3),
        "mask": torch.ones(n, 1, width, width),
        "light": torch.randn(n, 75, generator=g),
    }


def test_reinhard_round_trip():
    x = torch.linspace(0, 50, 101)
    torch.testing.assert_close(inverse_reinhard(reinhard(x)), x, rtol=1e-4, atol=1e-5)


@pytest.mark.parametrize("name", sorted(VARIANTS))
def test_every_variant_renders_hdr_maps(name):
    model = NDRModel(VARIANTS[name], **architecture(VARIANTS[name], SMALL))
    out = model(_batch())
    assert out["I_R"].shape == (2, 3, 32, 32)
    assert torch.isfinite(out["I_R"]).all() and (out["I_R"] >= 0).all()


def _zero_head_ndr() -> NDRModel:
    """The residual NDR with all-zero decoder heads: it adds nothing to the coarse shading."""
    model = NDRModel(VARIANTS["ndr"], **architecture(VARIANTS["ndr"], SMALL)).eval()
    for decoder in model.net.decoders:
        torch.nn.init.zeros_(decoder.head.weight)
        torch.nn.init.zeros_(decoder.head.bias)
    return model


def test_untrained_residual_model_renders_the_shading_input():
    """With zero decoder heads the residual NDR is exactly the coarse shading composite."""
    model = _zero_head_ndr()
    batch = _batch()
    out, expected = model(batch), shading_input(batch)
    for key in ("I_D", "I_S", "I_R"):
        torch.testing.assert_close(out[key], expected[key], rtol=1e-3, atol=1e-4)


def test_loss_is_zero_for_a_perfect_prediction():
    model = _zero_head_ndr()
    batch = _batch()
    batch["I_D"], batch["I_S"] = batch["S_D"], batch["S_S"]
    loss, logs, _ = loss_terms(model, batch)
    assert float(loss.detach()) < 1e-3 and set(logs) == {"dssim_I_D", "dssim_I_S", "dssim_I_R"}


def test_decoders_share_the_encoder_and_split_the_output():
    """One encoder feeds both decoders: a change of an encoder weight moves both halves of
    the output, a change of decoder 0's head only the first half."""
    torch.manual_seed(0)
    net = NDRNet(11, 3, [4, 8, 16], decoders=2).eval()
    x, light = torch.randn(1, 11, 16, 16), torch.randn(1, 75)
    before = net(x, light)
    assert before.shape == (1, 6, 16, 16)
    assert len(net.encoders) == 3  # one encoder path, not one per decoder
    with torch.no_grad():
        net.encoders[0][0][0].weight.add_(0.5)
    after = net(x, light)
    for half in (slice(0, 3), slice(3, 6)):
        assert not torch.allclose(after[:, half], before[:, half])
    with torch.no_grad():
        net.decoders[0].head.bias.add_(1.0)
    changed = net(x, light)
    assert not torch.allclose(changed[:, :3], after[:, :3])
    torch.testing.assert_close(changed[:, 3:], after[:, 3:])


def test_both_decoders_train_the_shared_encoder():
    """Each decoder's output alone sends gradient into the same first encoder weights."""
    net = NDRNet(11, 3, [4, 8], decoders=2)
    x, light = torch.randn(2, 11, 8, 8), torch.randn(2, 75)
    first = net.encoders[0][0][0].weight
    grads = []
    for half in (slice(0, 3), slice(3, 6)):
        net.zero_grad()
        net(x, light)[:, half].square().sum().backward()
        grads.append(first.grad.clone())
        assert first.grad.abs().sum() > 0
    assert not torch.allclose(grads[0], grads[1])


@pytest.mark.parametrize("conv_first", [False, True])
def test_each_decoder_level_convolves_at_the_resolution_its_order_says(conv_first):
    """The paper upsamples, then convolves; ours convolves at the coarser level first: the
    same weights and output size, the convolution on a quarter of the pixels."""
    net = NDRNet(11, 3, [4, 8, 16], decoders=1, conv_before_upsample=conv_first).eval()
    sizes = []
    for up in net.decoders[0].ups:
        conv = next(m for m in up.modules() if isinstance(m, torch.nn.Conv2d))
        conv.register_forward_hook(lambda m, x, y: sizes.append(x[0].shape[-1]))
    out = net(torch.randn(1, 11, 16, 16), torch.randn(1, 75))
    assert out.shape == (1, 3, 16, 16)
    assert sizes == ([4, 8] if conv_first else [8, 16])  # bottleneck 4 x 4
    paper = NDRNet(11, 3, [4, 8, 16], decoders=1, conv_before_upsample=False)
    assert count_parameters(net) == count_parameters(paper)


def test_light_and_input_size_are_checked():
    net = NDRNet(11, 3, [4, 8, 16], decoders=2)
    with pytest.raises(ValueError, match="pass the light vector"):
        net(torch.randn(1, 11, 16, 16))
    with pytest.raises(ValueError, match="divisible by 4"):
        net(torch.randn(1, 11, 18, 18), torch.randn(1, 75))


def test_light_input_changes_the_output():
    net = NDRNet(11, 3, [4, 8], decoders=2).eval()
    x = torch.randn(1, 11, 8, 8)
    assert not torch.allclose(net(x, torch.zeros(1, 75)), net(x, torch.ones(1, 75)))


@pytest.mark.parametrize("name", ["no_shading", "real_shading"])
def test_variants_without_the_shading_input_ignore_it(name):
    """No residual prior may leak the coarse shading into the shading-input ablation."""
    model = NDRModel(VARIANTS[name], **architecture(VARIANTS[name], SMALL)).eval()
    assert not model.residual
    batch = _batch()
    other = {**batch, "S_D": batch["S_D"] * 3, "S_S": batch["S_S"] * 0.1}
    torch.testing.assert_close(model(batch)["I_D"], model(other)["I_D"])


@pytest.mark.parametrize("name", sorted(VARIANTS))
def test_a_variant_is_built_only_from_the_keys_it_uses(name):
    """The training job gets only these keys: the network must not need any other."""
    variant = VARIANTS[name]
    arch = architecture(variant, SMALL)
    assert ("shading_residual" in arch) == variant.uses_prior
    assert ("widths" in arch) == (variant.arch == "ndr")
    model = NDRModel(variant, **arch)
    assert model.residual == variant.uses_prior


def test_the_specular_decoder_changes_nothing_on_diffuse_data():
    """On the diffuse data (``A_S = 0``; the loss leaves ``I_S`` out) ``ndr_diffuse``'s
    specular decoder gets no gradient, and the network without it, built under the same
    seed, predicts the same ``I_R`` before and after a training step (why the study's
    ``ndr_diffuse-decoder_I_S`` scores exactly as ``ndr_diffuse``)."""
    two = VARIANTS["ndr_diffuse"]
    one = dataclasses.replace(two, targets=("I_D",), decoders=1)
    batch = _batch()
    batch["A_S"] = batch["I_S"] = torch.zeros_like(batch["A_S"])
    outputs = []
    for variant in (two, one):
        torch.manual_seed(0)
        model = NDRModel(variant, **architecture(variant, SMALL))
        optimizer = torch.optim.Adam(model.parameters(), lr=1e-2)
        before = model(batch)["I_R"].detach()
        loss, _, _ = loss_terms(model, batch)
        loss.backward()
        if variant is two:
            specular = list(model.net.decoders[1].parameters())
            assert all(p.grad is None or not p.grad.any() for p in specular)
        optimizer.step()
        outputs.append((before, model.eval()(batch)["I_R"].detach()))
    for a, b in zip(*outputs, strict=True):
        torch.testing.assert_close(a, b)
    assert not torch.allclose(outputs[0][0], outputs[0][1])  # the step did train


def test_a_residual_builds_only_on_the_coarse_maps_it_is_given():
    """Without ``S_S`` among the inputs only ``I_D`` keeps its prior: with zero heads the
    network renders ``S_D`` exactly and no change of ``S_S`` reaches it."""
    variant = dataclasses.replace(
        VARIANTS["ndr_diffuse"], inputs=("N", "D", "S_D"), targets=("I_D",), decoders=1
    )
    assert variant.prior_targets == ("I_D",)
    model = NDRModel(variant, **architecture(variant, SMALL)).eval()
    torch.nn.init.zeros_(model.net.decoders[0].head.weight)
    torch.nn.init.zeros_(model.net.decoders[0].head.bias)
    batch = _batch()
    out = model(batch)
    torch.testing.assert_close(out["I_D"], batch["S_D"], rtol=1e-3, atol=1e-4)
    other = model({**batch, "S_S": batch["S_S"] * 5})
    torch.testing.assert_close(other["I_D"], out["I_D"])
