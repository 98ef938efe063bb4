"""Trained networks prepared for fast inference.

A DeepPRT-style renderer runs a trained network once per frame, so its cost is the
inference time of a batch of one. Two standard steps cut that on a CPU: batch norm folded
into the convolution before it (``torch.nn.utils.fusion.fuse_conv_bn_eval``: one pass
over the activations less per layer) and channels-last memory (the layout oneDNN's and
cuDNN's fastest convolution kernels use). Neither changes what the network computes beyond
float rounding.
"""

from __future__ import annotations

import copy

import torch
from torch import nn
from torch.nn.utils.fusion import fuse_conv_bn_eval


def fold_batch_norms(model: nn.Module) -> nn.Module:
    """Copy of an eval-mode ``model`` with every ``Conv2d, BatchNorm2d`` pair of an
    ``nn.Sequential`` replaced by one convolution (the batch norm by an identity)."""
    model = copy.deepcopy(model).eval()
    for seq in model.modules():
        if not isinstance(seq, nn.Sequential):
            continue
        for i in range(len(seq) - 1):
            conv, bn = seq[i], seq[i + 1]
            if isinstance(conv, nn.Conv2d) and isinstance(bn, nn.BatchNorm2d):
                seq[i] = fuse_conv_bn_eval(conv, bn)
                seq[i + 1] = nn.Identity()
    return model


def prepare_for_inference(model: nn.Module) -> nn.Module:
    """Eval-mode, batch-norm-folded, channels-last copy of ``model``.

    It computes ``model(x)`` for inputs ``(B, C, H, W)`` in either memory layout (pass
    channels-last inputs to skip a conversion).
    """
    return fold_batch_norms(model).to(memory_format=torch.channels_last)
