import numpy as np
import pytest
import torch
from skimage.metrics import structural_similarity

from neurender import metrics


def _pair(seed=0, shape=(2, 3, 48, 40)):
    g = torch.Generator().manual_seed(seed)
    a = torch.rand(shape, generator=g, dtype=torch.float64)
    b = (a + 0.1 * torch.randn(shape, generator=g, dtype=torch.float64)).clamp(0, 1)
    return a, b


def test_ssim_matches_skimage():
    a, b = _pair()
    ours = metrics.ssim_map(a, b)[..., 5:-5, 5:-5].flatten(1).mean(1)
    for i in range(a.shape[0]):
        ref = structural_similarity(
            a[i].numpy(),
            b[i].numpy(),
            channel_axis=0,
            gaussian_weights=True,
            sigma=1.5,
            use_sample_covariance=False,
            data_range=1.0,
        )
        assert abs(float(ours[i]) - ref) < 1e-3


def test_ssim_identity_and_dssim():
    a, b = _pair(1)
    torch.testing.assert_close(metrics.ssim(a, a), torch.ones(2, dtype=torch.float64))
    torch.testing.assert_close(metrics.dssim(a, b), (1 - metrics.ssim(a, b)) / 2)


def test_l1_l2_psnr_analytic():
    a = torch.zeros(1, 1, 4, 4)
    b = torch.full((1, 1, 4, 4), 0.1)
    assert float(metrics.l1(a, b)) == pytest.approx(0.1)
    assert float(metrics.l2(a, b)) == pytest.approx(0.01)
    assert float(metrics.psnr(a, b)) == pytest.approx(20.0)


def test_masked_metrics_ignore_outside():
    a = torch.zeros(1, 3, 8, 8)
    b = torch.zeros(1, 3, 8, 8)
    b[..., :, 4:] = 5.0  # error only where the mask is 0
    mask = torch.zeros(1, 1, 8, 8)
    mask[..., :, :4] = 1
    assert float(metrics.l1(a, b, mask)) == 0.0
    assert float(metrics.l1(a, b)) == pytest.approx(2.5)
    assert np.isnan(float(metrics.l1(a, b, torch.zeros(1, 1, 8, 8))))


def test_shape_mismatch_raises():
    with pytest.raises(ValueError, match="one shape"):
        metrics.l1(torch.zeros(1, 1, 4, 4), torch.zeros(1, 1, 4, 5))
