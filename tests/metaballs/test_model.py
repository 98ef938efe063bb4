import pytest
import torch

from neurender.metaballs import DEMO_VARIANTS, VARIANTS, gbuffers, model, trained_variants


def test_residual_generator_starts_at_its_prior():
    torch.manual_seed(0)
    net = model.build_generator(32, 4, "sphere_residual")
    x = torch.rand(2, model.input_channels("sphere_residual"), 32, 32) * 2 - 1
    torch.testing.assert_close(net(x), x[:, -gbuffers.CHANNELS :])


def test_plain_generator_outputs_g_buffers_through_tanh():
    torch.manual_seed(0)
    plain = model.build_generator(32, 4, "pix2pix")
    out = plain(torch.rand(2, model.input_channels("pix2pix"), 32, 32) * 100)
    assert out.shape == (2, gbuffers.CHANNELS, 32, 32) and out.abs().max() <= 1


@pytest.mark.parametrize("variant", VARIANTS)
def test_network_inputs_have_the_variants_channels(variant, make_scene):
    scene = make_scene([[0.0, 0.0, 12.0], [1.0, 1.0, 16.0]], [1.0, 1.5])
    x = model.network_inputs(scene, 16, variant)
    assert x.shape == (model.input_channels(variant), 16, 16) and x.dtype == torch.float32
    assert 0 <= x.min() and x.max() <= 1


def test_unknown_variant_is_named():
    with pytest.raises(ValueError, match="'gan'.*expected one of"):
        model.input_channels("gan")


def test_width_not_a_power_of_two_is_refused():
    with pytest.raises(ValueError, match="width=48.*power of two"):
        model.build_generator(48, 4, "pix2pix")


def test_trained_variants_keep_the_demos_and_the_table_order():
    assert trained_variants(["sphere_residual", "l1only"]) == VARIANTS
    assert trained_variants(["pix2pix"]) == DEMO_VARIANTS
    with pytest.raises(ValueError, match="'gan'"):
        trained_variants(["gan"])
