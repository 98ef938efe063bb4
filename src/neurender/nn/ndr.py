"""The NDR U-Net (Suppan et al. 2021, Fig. 2 and 4): building blocks in one readable file.

One encoder over the screen-space buffers; the light's SH vector passes through two fully
connected layers and is tiled and concatenated at every bottleneck position; one or more
parallel decoders share the bottleneck and the skip connections. Each level is two
conv 3x3 + batch norm + ReLU; downsampling by stride-2 convolution, upsampling bilinear
followed by a convolution (the paper's), or the convolution first, at the coarser level
(``conv_before_upsample``: a quarter of that convolution's work and the same receptive
field; the shipped NDR graph's full-resolution convolutions are most of its time). Outputs
are logits (the caller applies the sigmoid, possibly
after adding a prior). Tensors are ``(B, C, H, W)``; H and W divisible by
``2 ** (len(widths) - 1)``.
"""

from __future__ import annotations

import torch
from torch import nn

from neurender.nn.unet import conv_bn_relu


def double_conv(cin: int, cout: int) -> nn.Sequential:
    return nn.Sequential(conv_bn_relu(cin, cout), conv_bn_relu(cout, cout))


class Decoder(nn.Module):
    """Upsampling path from the bottleneck to ``out_channels`` logits at full resolution.

    Args:
        skip_widths: encoder widths, finest first (the skips it concatenates).
        bottleneck: channels of the bottleneck tensor it starts from.
        widths: its own channels per level, finest first (``len(skip_widths) - 1`` used).
        conv_before_upsample: each level's first convolution before the upsampling, at
            the coarser resolution (else after it, as the paper's).
    """

    def __init__(
        self,
        skip_widths: list[int],
        bottleneck: int,
        widths: list[int],
        out_channels: int,
        conv_before_upsample: bool = False,
    ):
        super().__init__()
        self.ups = nn.ModuleList()
        self.blocks = nn.ModuleList()
        cin = bottleneck
        for level in range(len(skip_widths) - 2, -1, -1):
            up = nn.Upsample(scale_factor=2, mode="bilinear", align_corners=False)
            conv = conv_bn_relu(cin, widths[level])
            self.ups.append(nn.Sequential(*((conv, up) if conv_before_upsample else (up, conv))))
            self.blocks.append(double_conv(widths[level] + skip_widths[level], widths[level]))
            cin = widths[level]
        self.head = nn.Conv2d(cin, out_channels, 1)

    def forward(self, bottleneck: torch.Tensor, skips: list[torch.Tensor]) -> torch.Tensor:
        """``(B, bottleneck, h, w)`` and finest-first skips -> ``(B, out_channels, H, W)``."""
        h = bottleneck
        for up, block, skip in zip(self.ups, self.blocks, reversed(skips[:-1]), strict=True):
            h = block(torch.cat([up(h), skip], 1))
        return self.head(h)


class NDRNet(nn.Module):
    """Encoder, optional SH injection at the bottleneck, ``decoders`` parallel decoders.

    Args:
        in_channels: buffer channels (NDR: N 3 + R 1 + D 1 + S_D 3 + S_S 3 = 11).
        out_channels: logits per decoder (3: one RGB shading map each).
        widths: encoder channels per level, finest first.
        decoders: number of parallel decoders (NDR 2; the separation ablation 1).
        decoder_scale: decoder width multiplier (the single-decoder ablation uses 2).
        sh_features: light vector length (75 = 5-band SH x RGB), 0 for none.
        sh_hidden: width of the two fully connected layers.
        conv_before_upsample: the decoders' upsampling after each level's first
            convolution (see the module docstring; the paper's order when False).

    ``forward(x, light)`` returns ``(B, decoders * out_channels, H, W)`` logits, decoder
    outputs concatenated in order.
    """

    def __init__(
        self,
        in_channels: int,
        out_channels: int,
        widths: list[int],
        decoders: int = 2,
        decoder_scale: int = 1,
        sh_features: int = 75,
        sh_hidden: int = 128,
        conv_before_upsample: bool = False,
    ):
        super().__init__()
        if len(widths) < 2:
            raise ValueError(f"widths={widths}: the U-Net needs at least two levels")
        self.levels = len(widths)
        self.encoders = nn.ModuleList([double_conv(in_channels, widths[0])])
        for i in range(1, len(widths)):
            self.encoders.append(
                nn.Sequential(
                    conv_bn_relu(widths[i - 1], widths[i], stride=2),
                    conv_bn_relu(widths[i], widths[i]),
                )
            )
        self.light = (
            nn.Sequential(
                nn.Linear(sh_features, sh_hidden),
                nn.ReLU(inplace=True),
                nn.Linear(sh_hidden, sh_hidden),
                nn.ReLU(inplace=True),
            )
            if sh_features
            else None
        )
        bottleneck = widths[-1] + (sh_hidden if sh_features else 0)
        self.fuse = conv_bn_relu(bottleneck, widths[-1] * decoder_scale)
        self.decoders = nn.ModuleList(
            Decoder(
                widths,
                widths[-1] * decoder_scale,
                [w * decoder_scale for w in widths],
                out_channels,
                conv_before_upsample,
            )
            for _ in range(decoders)
        )

    def forward(self, x: torch.Tensor, light: torch.Tensor | None = None) -> torch.Tensor:
        """``(B, in_channels, H, W)`` and ``(B, sh_features)`` -> logits (see class doc)."""
        factor = 2 ** (self.levels - 1)
        if x.shape[-1] % factor or x.shape[-2] % factor:
            raise ValueError(f"input {tuple(x.shape)}: H and W must be divisible by {factor}")
        skips = []
        h = x
        for enc in self.encoders:
            h = enc(h)
            skips.append(h)
        if self.light is not None:
            if light is None:
                raise ValueError(
                    "this NDRNet was built with sh_features > 0: pass the light vector"
                )
            code = self.light(light)[:, :, None, None].expand(-1, -1, h.shape[2], h.shape[3])
            h = torch.cat([h, code], 1)
        h = self.fuse(h)
        return torch.cat([dec(h, skips) for dec in self.decoders], 1)
