import torch
from torch import nn

from neurender.nn.inference import fold_batch_norms, prepare_for_inference
from neurender.nn.unet import ResUNet


def _trained_looking_unet() -> ResUNet:
    """A U-Net whose batch norms hold non-trivial running statistics and affine terms."""
    torch.manual_seed(0)
    model = ResUNet(6, 5, [8, 16], blocks=1)
    model.train()
    with torch.no_grad():
        for bn in (m for m in model.modules() if isinstance(m, nn.BatchNorm2d)):
            bn.weight.uniform_(0.5, 2.0)
            bn.bias.uniform_(-0.5, 0.5)
        for _ in range(3):
            model(torch.randn(4, 6, 16, 16) * 2 + 0.5)
    return model.eval()


def test_prepared_network_computes_the_eager_network():
    model = _trained_looking_unet()
    x = torch.randn(3, 6, 16, 16)
    with torch.no_grad():
        expected = model(x)
        fast = prepare_for_inference(model)
        for layout in (torch.contiguous_format, torch.channels_last):
            torch.testing.assert_close(
                fast(x.to(memory_format=layout)), expected, atol=1e-5, rtol=1e-4
            )


def test_every_batch_norm_is_folded_and_the_original_is_untouched():
    model = _trained_looking_unet()
    n_bn = sum(isinstance(m, nn.BatchNorm2d) for m in model.modules())
    folded = fold_batch_norms(model)
    assert n_bn > 0
    assert not any(isinstance(m, nn.BatchNorm2d) for m in folded.modules())
    assert sum(isinstance(m, nn.BatchNorm2d) for m in model.modules()) == n_bn
    assert next(prepare_for_inference(model).stem[0].parameters()).is_contiguous(
        memory_format=torch.channels_last
    )
