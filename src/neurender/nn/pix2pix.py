"""pix2pix building blocks (Isola et al. 2017), after the authors' ``models/networks.py``.

Generator: U-Net with ``num_downs`` stride-2 4x4 convolutions (LeakyReLU 0.2 before each
down-convolution but the first, batch norm except at the outermost and innermost levels),
ReLU + 4x4 transposed convolutions on the way up, dropout 0.5 in the three innermost
decoders below the bottleneck, skip connections, tanh output. Discriminator: PatchGAN
(``n_layers`` stride-2 4x4 convolutions, 70x70 receptive field for 3 layers) on the
concatenation of input and output. Tensors ``(B, C, H, W)`` in [-1, 1]; H = W = 2**num_downs
for a 1x1 bottleneck.
"""

from __future__ import annotations

import torch
from torch import nn


class UnetSkipConnectionBlock(nn.Module):
    """One U-Net level: down, the nested ``submodule``, up, concatenated with its input."""

    def __init__(
        self,
        outer_nc: int,
        inner_nc: int,
        input_nc: int | None = None,
        submodule: nn.Module | None = None,
        outermost: bool = False,
        innermost: bool = False,
        use_dropout: bool = False,
        output_tanh: bool = True,
    ):
        super().__init__()
        self.outermost = outermost
        input_nc = outer_nc if input_nc is None else input_nc
        downconv = nn.Conv2d(input_nc, inner_nc, 4, stride=2, padding=1, bias=False)
        downrelu = nn.LeakyReLU(0.2, True)
        uprelu = nn.ReLU(True)
        if outermost:
            upconv = nn.ConvTranspose2d(inner_nc * 2, outer_nc, 4, stride=2, padding=1)
            model = [downconv, submodule, uprelu, upconv]
            if output_tanh:
                model.append(nn.Tanh())
        elif innermost:
            upconv = nn.ConvTranspose2d(inner_nc, outer_nc, 4, stride=2, padding=1, bias=False)
            model = [downrelu, downconv, uprelu, upconv, nn.BatchNorm2d(outer_nc)]
        else:
            upconv = nn.ConvTranspose2d(inner_nc * 2, outer_nc, 4, stride=2, padding=1, bias=False)
            model = [
                downrelu,
                downconv,
                nn.BatchNorm2d(inner_nc),
                submodule,
                uprelu,
                upconv,
                nn.BatchNorm2d(outer_nc),
            ]
            if use_dropout:
                model.append(nn.Dropout(0.5))
        self.model = nn.Sequential(*model)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if self.outermost:
            return self.model(x)
        return torch.cat([x, self.model(x)], 1)


class UnetGenerator(nn.Module):
    """pix2pix U-Net generator.

    Args:
        input_nc, output_nc: channels in and out (4 and 7 for metaballs).
        num_downs: number of downsamplings (log2(W) for a 1x1 bottleneck).
        ngf: filters of the outermost level (doubling up to 8 ngf).
        output_tanh: end with tanh (pix2pix); without it the output is unbounded, e.g. a
            correction added to a prior.
    """

    def __init__(
        self, input_nc: int, output_nc: int, num_downs: int, ngf: int = 64, output_tanh: bool = True
    ):
        super().__init__()
        if num_downs < 5:
            raise ValueError(f"num_downs={num_downs}: the pix2pix U-Net needs at least 5 levels")
        block = UnetSkipConnectionBlock(ngf * 8, ngf * 8, innermost=True)
        for _ in range(num_downs - 5):
            block = UnetSkipConnectionBlock(ngf * 8, ngf * 8, submodule=block, use_dropout=True)
        block = UnetSkipConnectionBlock(ngf * 4, ngf * 8, submodule=block)
        block = UnetSkipConnectionBlock(ngf * 2, ngf * 4, submodule=block)
        block = UnetSkipConnectionBlock(ngf, ngf * 2, submodule=block)
        self.model = UnetSkipConnectionBlock(
            output_nc,
            ngf,
            input_nc=input_nc,
            submodule=block,
            outermost=True,
            output_tanh=output_tanh,
        )
        self.num_downs = num_downs

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """``(B, input_nc, H, W) -> (B, output_nc, H, W)``, in [-1, 1] with ``output_tanh``."""
        factor = 2**self.num_downs
        if x.shape[-1] % factor or x.shape[-2] % factor:
            raise ValueError(f"input {tuple(x.shape)}: H and W must be divisible by {factor}")
        return self.model(x)


class NLayerDiscriminator(nn.Module):
    """PatchGAN: a map of real/fake logits, one per overlapping patch."""

    def __init__(self, input_nc: int, ndf: int = 64, n_layers: int = 3):
        super().__init__()
        layers: list[nn.Module] = [
            nn.Conv2d(input_nc, ndf, 4, stride=2, padding=1),
            nn.LeakyReLU(0.2, True),
        ]
        mult = 1
        for n in range(1, n_layers + 1):
            prev, mult = mult, min(2**n, 8)
            stride = 2 if n < n_layers else 1
            layers += [
                nn.Conv2d(ndf * prev, ndf * mult, 4, stride=stride, padding=1, bias=False),
                nn.BatchNorm2d(ndf * mult),
                nn.LeakyReLU(0.2, True),
            ]
        layers.append(nn.Conv2d(ndf * mult, 1, 4, stride=1, padding=1))
        self.model = nn.Sequential(*layers)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """``(B, input_nc, H, W) -> (B, 1, h, w)`` logits."""
        return self.model(x)


def init_weights(net: nn.Module, gain: float = 0.02) -> nn.Module:
    """pix2pix init: conv weights N(0, gain), batch-norm weights N(1, gain), biases 0."""

    def init(m: nn.Module) -> None:
        if isinstance(m, nn.Conv2d | nn.ConvTranspose2d):
            nn.init.normal_(m.weight, 0.0, gain)
            if m.bias is not None:
                nn.init.zeros_(m.bias)
        elif isinstance(m, nn.BatchNorm2d):
            nn.init.normal_(m.weight, 1.0, gain)
            nn.init.zeros_(m.bias)

    return net.apply(init)
