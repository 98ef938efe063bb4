import pytest
import torch

from neurender.nn.unet import ResUNet, count_parameters


@pytest.mark.parametrize("widths", [[8], [8, 16], [8, 16, 32]])
def test_shapes_and_sigmoid_range(widths):
    net = ResUNet(6, 5, widths).eval()
    out = net(torch.randn(2, 6, 16, 16) * 10)
    assert out.shape == (2, 5, 16, 16)
    assert out.min() > 0 and out.max() < 1


def test_paper_size_has_about_11_8_million_parameters():
    # DeepPRT 3.2.4: "approximately 11.8 million parameters"
    assert abs(count_parameters(ResUNet(6, 16, [64, 128, 256, 512])) - 11.8e6) < 0.15e6


@pytest.mark.parametrize("level", [0, 1])
def test_skip_connections_carry_each_level_to_the_decoder(level):
    # Cut the path down through the coarser levels (detach the features entering the
    # next downsampling): the output still depends on this level's features only through
    # its skip connection. A U-Net without skips has no gradient left here.
    torch.manual_seed(0)
    net = ResUNet(1, 1, [4, 8, 16]).eval()
    features = {}
    net.encoders[level].register_forward_hook(lambda m, i, out: features.setdefault("f", out))
    net.downs[level].register_forward_pre_hook(lambda m, args: (args[0].detach(),))
    out = net(torch.randn(1, 1, 16, 16))
    (grad,) = torch.autograd.grad(out.sum(), features["f"], allow_unused=True)
    assert grad is not None and grad.abs().sum() > 0


def test_receptive_field_spans_the_image():
    # Far pixels reach an output pixel through the coarse levels.
    torch.manual_seed(0)
    net = ResUNet(1, 1, [4, 8, 16]).eval()
    x = torch.randn(1, 1, 16, 16, requires_grad=True)
    net(x)[0, 0, 5, 7].backward()
    assert x.grad[0, 0, 5, 7].abs() > 0 and x.grad[0, 0, 15, 15].abs() > 0


def test_indivisible_input_raises():
    with pytest.raises(ValueError, match="divisible by 4"):
        ResUNet(6, 16, [8, 16, 32])(torch.zeros(1, 6, 18, 18))
