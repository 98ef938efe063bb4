"""Image metrics on ``(B, C, H, W)`` tensors, each returning one value per image ``(B,)``.

SSIM follows Wang et al. 2004 (11 x 11 Gaussian window, sigma 1.5, K1 = 0.01, K2 = 0.03)
through ``kornia.metrics.ssim``; DSSIM = (1 - SSIM) / 2. ``data_range`` is the value
range of the images (1 for images in [0, 1]). Masks are ``(B, 1, H, W)`` or
``(B, C, H, W)`` with values in {0, 1}; a masked metric averages over masked pixels only
and is NaN for an image whose mask is empty.
"""

from __future__ import annotations

import kornia
import torch

SSIM_WINDOW = 11


def _check_pair(a: torch.Tensor, b: torch.Tensor) -> None:
    if a.shape != b.shape or a.ndim != 4:
        raise ValueError(
            "expected two (B, C, H, W) tensors of one shape, "
            f"got {tuple(a.shape)} and {tuple(b.shape)}"
        )


def _masked_mean(values: torch.Tensor, mask: torch.Tensor | None) -> torch.Tensor:
    """Mean over (C, H, W) of ``values`` (B, C, H, W), restricted to ``mask``."""
    if mask is None:
        return values.flatten(1).mean(1)
    m = mask.to(values.dtype).expand_as(values)
    return (values * m).flatten(1).sum(1) / m.flatten(1).sum(1)


def ssim_map(a: torch.Tensor, b: torch.Tensor, data_range: float = 1.0) -> torch.Tensor:
    """Per-pixel SSIM ``(B, C, H, W)``; borders use kornia's 'same' (reflect) padding."""
    _check_pair(a, b)
    return kornia.metrics.ssim(a, b, SSIM_WINDOW, max_val=data_range, padding="same")


def ssim(
    a: torch.Tensor, b: torch.Tensor, mask: torch.Tensor | None = None, data_range: float = 1.0
) -> torch.Tensor:
    """Mean SSIM per image ``(B,)`` (within ``mask`` if given)."""
    return _masked_mean(ssim_map(a, b, data_range), mask)


def dssim(
    a: torch.Tensor, b: torch.Tensor, mask: torch.Tensor | None = None, data_range: float = 1.0
) -> torch.Tensor:
    """Structural dissimilarity ``(1 - SSIM) / 2`` per image ``(B,)``."""
    return (1.0 - ssim(a, b, mask, data_range)) / 2.0


def l1(a: torch.Tensor, b: torch.Tensor, mask: torch.Tensor | None = None) -> torch.Tensor:
    """Mean absolute error per image ``(B,)``."""
    _check_pair(a, b)
    return _masked_mean((a - b).abs(), mask)


def l2(a: torch.Tensor, b: torch.Tensor, mask: torch.Tensor | None = None) -> torch.Tensor:
    """Mean squared error per image ``(B,)``."""
    _check_pair(a, b)
    return _masked_mean((a - b).square(), mask)


def psnr(
    a: torch.Tensor, b: torch.Tensor, mask: torch.Tensor | None = None, data_range: float = 1.0
) -> torch.Tensor:
    """Peak signal-to-noise ratio in dB per image ``(B,)``: ``10 log10(range^2 / MSE)``."""
    return 10.0 * torch.log10(data_range**2 / l2(a, b, mask))
