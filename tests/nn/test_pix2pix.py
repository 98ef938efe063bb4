import pytest
import torch

from neurender.nn.pix2pix import NLayerDiscriminator, UnetGenerator, init_weights


def test_generator_shapes_range_and_dropout_levels():
    g = init_weights(UnetGenerator(4, 7, num_downs=7, ngf=8))
    out = g(torch.randn(2, 4, 128, 128))
    assert out.shape == (2, 7, 128, 128) and out.abs().max() <= 1
    # dropout sits in the num_downs - 5 = 2 innermost decoders below the ngf*8 levels
    assert sum(isinstance(m, torch.nn.Dropout) for m in g.modules()) == 2


def test_generator_paper_depth_has_three_dropout_decoders():
    g = UnetGenerator(4, 7, num_downs=8, ngf=4)
    assert sum(isinstance(m, torch.nn.Dropout) for m in g.modules()) == 3


def test_patchgan_receptive_field_is_70_pixels():
    d = NLayerDiscriminator(11, ndf=4).eval()
    x = torch.zeros(1, 11, 128, 128, requires_grad=True)
    d(x)[0, 0, 7, 7].backward()
    cols = (x.grad.abs().sum((0, 1, 2)) > 0).nonzero()
    assert int(cols.max() - cols.min() + 1) == 70


def test_init_weights_statistics():
    g = init_weights(UnetGenerator(4, 7, num_downs=5, ngf=16))
    w = torch.cat(
        [m.weight.detach().flatten() for m in g.modules() if isinstance(m, torch.nn.Conv2d)]
    )
    assert abs(float(w.std()) - 0.02) < 0.002


def test_indivisible_input_raises():
    with pytest.raises(ValueError, match="divisible by 32"):
        UnetGenerator(4, 7, num_downs=5, ngf=4)(torch.zeros(1, 4, 48, 48))
