"""ResNet U-Net of DeepPRT (paper 3.2.1): building blocks in one readable file.

Encoder and decoder are sequences of ResNet blocks (conv 3x3, batch norm, ReLU), the
encoder downsamples with stride-2 convolutions (no pooling), every encoder level feeds the
decoder level of the same size through a skip connection, and the last layer is a sigmoid.
Tensors are ``(B, C, H, W)``; H and W must be divisible by ``2 ** (len(widths) - 1)``.
"""

from __future__ import annotations

import torch
from torch import nn


def conv_bn_relu(cin: int, cout: int, stride: int = 1) -> nn.Sequential:
    """3x3 convolution, batch norm, ReLU."""
    return nn.Sequential(
        nn.Conv2d(cin, cout, 3, stride=stride, padding=1, bias=False),
        nn.BatchNorm2d(cout),
        nn.ReLU(inplace=True),
    )


class ResBlock(nn.Module):
    """He et al. basic block: two 3x3 conv + BN, identity (or 1x1 projection) shortcut."""

    def __init__(self, cin: int, cout: int):
        super().__init__()
        self.body = nn.Sequential(
            nn.Conv2d(cin, cout, 3, padding=1, bias=False),
            nn.BatchNorm2d(cout),
            nn.ReLU(inplace=True),
            nn.Conv2d(cout, cout, 3, padding=1, bias=False),
            nn.BatchNorm2d(cout),
        )
        self.shortcut = (
            nn.Identity()
            if cin == cout
            else nn.Sequential(nn.Conv2d(cin, cout, 1, bias=False), nn.BatchNorm2d(cout))
        )
        self.act = nn.ReLU(inplace=True)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """``(B, cin, H, W) -> (B, cout, H, W)``."""
        return self.act(self.body(x) + self.shortcut(x))


def res_stack(cin: int, cout: int, blocks: int) -> nn.Sequential:
    return nn.Sequential(*[ResBlock(cin if i == 0 else cout, cout) for i in range(blocks)])


class ResUNet(nn.Module):
    """U-Net of ResNet blocks.

    Args:
        in_channels: input channels (6 for P and N images).
        out_channels: output channels (16 diffuse or 48 glossy coefficients).
        widths: channels per level, finest first; each level after the first halves H, W.
        blocks: ResNet blocks per level in the encoder and in the decoder.
    """

    def __init__(self, in_channels: int, out_channels: int, widths: list[int], blocks: int = 1):
        super().__init__()
        if not widths:
            raise ValueError("widths must list at least one level")
        self.levels = len(widths)
        self.stem = conv_bn_relu(in_channels, widths[0])
        self.encoders = nn.ModuleList([res_stack(widths[0], widths[0], blocks)])
        self.downs = nn.ModuleList()
        for i in range(1, len(widths)):
            self.downs.append(conv_bn_relu(widths[i - 1], widths[i], stride=2))
            self.encoders.append(res_stack(widths[i], widths[i], blocks))
        self.ups = nn.ModuleList()
        self.decoders = nn.ModuleList()
        for i in range(len(widths) - 1, 0, -1):
            self.ups.append(
                nn.Sequential(
                    nn.Upsample(scale_factor=2, mode="bilinear", align_corners=False),
                    conv_bn_relu(widths[i], widths[i - 1]),
                )
            )
            self.decoders.append(res_stack(2 * widths[i - 1], widths[i - 1], blocks))
        self.head = nn.Conv2d(widths[0], out_channels, 1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """``(B, in_channels, H, W) -> (B, out_channels, H, W)`` in (0, 1)."""
        factor = 2 ** (self.levels - 1)
        if x.shape[-1] % factor or x.shape[-2] % factor:
            raise ValueError(f"input {tuple(x.shape)}: H and W must be divisible by {factor}")
        skips = []
        h = self.encoders[0](self.stem(x))
        skips.append(h)
        for down, enc in zip(self.downs, self.encoders[1:], strict=True):
            h = enc(down(h))
            skips.append(h)
        for up, dec, skip in zip(self.ups, self.decoders, reversed(skips[:-1]), strict=True):
            h = dec(torch.cat([up(h), skip], dim=1))
        return torch.sigmoid(self.head(h))


def count_parameters(model: nn.Module) -> int:
    """Number of trainable parameters."""
    return sum(p.numel() for p in model.parameters() if p.requires_grad)
