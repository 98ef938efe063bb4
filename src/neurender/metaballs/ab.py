"""AB images (thesis 5.2.4): one RGBA PNG of ``3W x W`` per example.

Panels, left to right: [input RGB, input depth in A | target colour RGB, target depth in
A | target normals RGB, A unused (255)]. Values in [0, 1] are stored as 8-bit. Targets
are G-buffer stacks of :mod:`neurender.metaballs.gbuffers`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from neurender import io
from neurender.metaballs.gbuffers import COLOUR, DEPTH, NORMAL, stack


def pack(inputs: torch.Tensor, target: torch.Tensor) -> np.ndarray:
    """``(W, 3W, 4)`` uint8 AB image of the circles ``(4, W, W)`` and the target G-buffer
    stack ``(7, W, W)``, both in [0, 1]."""
    ones = torch.ones_like(target[DEPTH])
    panels = [inputs, torch.cat([target[COLOUR], target[DEPTH]]), torch.cat([target[NORMAL], ones])]
    rgba = torch.cat([p.detach().cpu().double() for p in panels], dim=2)  # (4, W, 3W)
    return io.to_uint8(rgba.permute(1, 2, 0).numpy())


def unpack(image: np.ndarray) -> dict[str, torch.Tensor]:
    """Split an AB image ``(W, 3W, 4)`` uint8 into float32 tensors in [0, 1]: the circles
    ``inputs (4, W, W)`` and the G-buffer stack ``target (7, W, W)``."""
    h, w3, c = image.shape
    if c != 4 or w3 != 3 * h:
        raise ValueError(f"AB image of shape {image.shape}: expected (W, 3W, 4)")
    x = torch.from_numpy(image.astype(np.float32) / 255.0).permute(2, 0, 1)
    a, b, n = x[:, :, :h], x[:, :, h : 2 * h], x[:, :, 2 * h :]
    return {"inputs": a, "target": stack(b[:3], b[3:], n[:3])}


def write_ab(path: str | Path, image: np.ndarray) -> None:
    io.write_png(path, image)


def read_ab(path: str | Path) -> dict[str, torch.Tensor]:
    """:func:`unpack` of the AB image at ``path`` (errors name the file)."""
    image = io.read_png(path)
    if image.dtype != np.uint8:
        raise ValueError(f"AB image {path} is {image.dtype}; expected 8-bit RGBA")
    try:
        return unpack(image)
    except ValueError as err:
        raise ValueError(f"{path}: {err}") from err
