import pytest
import torch
from torch import nn

from neurender.nn.norms import PixelNorm, centre_pixel_norm_inputs


def test_pixel_norm_is_a_layer_norm_over_each_pixels_channels():
    """An independent implementation: torch's layer norm over the channels of every pixel,
    with the same affine map."""
    norm = PixelNorm(5)
    with torch.no_grad():
        norm.weight.normal_(generator=torch.Generator().manual_seed(0))
        norm.bias.normal_(generator=torch.Generator().manual_seed(1))
    x = 3 * torch.randn(2, 5, 4, 3, generator=torch.Generator().manual_seed(2)) + 1
    expected = torch.nn.functional.layer_norm(
        x.permute(0, 2, 3, 1), (5,), norm.weight.flatten(), norm.bias.flatten(), norm.eps
    ).permute(0, 3, 1, 2)
    torch.testing.assert_close(norm(x), expected, atol=1e-5, rtol=1e-5)
    assert "average" not in norm.state_dict()  # checkpoints keep their keys


def _conv_norm_stack(bias: bool) -> nn.Sequential:
    """Convolutions (one dilated, one 1x1) each before a pixel norm with a non-trivial
    affine map, as a trained :class:`neurender.prt.local_model.DilatedNet`."""
    torch.manual_seed(0)
    layers = []
    for cin, k, d in ((3, 3, 2), (6, 1, 1)):
        layers += [nn.Conv2d(cin, 6, k, padding=d * (k // 2), dilation=d, bias=bias)]
        layers += [PixelNorm(6), nn.ReLU()]
    model = nn.Sequential(*layers)
    with torch.no_grad():
        for norm in model[1::3]:
            norm.weight.uniform_(0.5, 2.0)
            norm.bias.uniform_(-0.5, 0.5)
    return model.eval()


@pytest.mark.parametrize("bias", [True, False])
def test_centred_convolutions_compute_the_same_and_leave_the_original(bias):
    model = _conv_norm_stack(bias)
    x = 2 * torch.randn(2, 3, 9, 7) + 1  # borders: the zero padding must stay exact
    folded = centre_pixel_norm_inputs(model)
    with torch.no_grad():
        torch.testing.assert_close(folded(x), model(x), atol=1e-5, rtol=1e-5)
        # Each folded convolution's output has zero channel mean at every pixel.
        assert folded[0](x).mean(1).abs().max() < 1e-5
    assert all(norm.input_centred for norm in folded[1::3])
    assert not any(norm.input_centred for norm in model[1::3])
    assert list(folded.state_dict()) == list(model.state_dict())
