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


def test_skip_connections_carry_fine_detail():
    # The output pixel depends on its own input pixel, and far pixels reach it only
    # through the coarse levels: the receptive field spans the image.
    torch.manual_seed(0)
    net = ResUNet(1, 1, [4, 8, 16]).eval()
    x = torch.randn(1, 1, 16, 16, requires_grad=True)
    net(x)[0, 0, 5, 7].backward()
    assert x.grad[0, 0, 5, 7].abs() > 0
    assert x.grad[0, 0, 15, 15].abs() > 0


def test_indivisible_input_raises():
    with pytest.raises(ValueError, match="divisible by 4"):
        ResUNet(6, 16, [8, 16, 32])(torch.zeros(1, 6, 18, 18))
