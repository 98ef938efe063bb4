"""The training examples of a split as network pairs, with exact mirrorings.

Items are ``(input (C, W, W), target (7, W, W))`` float32 in [-1, 1]: a variant's input of
:func:`neurender.metaballs.model.network_inputs` and the example's G-buffer stack
(:mod:`neurender.metaballs.gbuffers`), read from AB images (:mod:`neurender.metaballs.ab`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch
from torch.utils.data import Dataset

from neurender import io
from neurender.metaballs import MIRRORINGS, ab, gbuffers
from neurender.metaballs.data import read_scenes
from neurender.metaballs.model import CIRCLE_CHANNELS, network_inputs, uses_spheres


def flip(
    x: torch.Tensor, y: torch.Tensor, horizontal: bool, vertical: bool, spheres: bool
) -> tuple[torch.Tensor, torch.Tensor]:
    """Mirror an ``(input, target)`` pair in [-1, 1] across the image's vertical and/or
    horizontal centre line: the camera is symmetric, so this is the mirrored scene's
    example. The target (and, with ``spheres``, the impostors after the circles) mirror
    by :func:`neurender.metaballs.gbuffers.mirror`; circles just flip."""
    for flag, dim, axis in ((horizontal, -1, 0), (vertical, -2, 1)):
        if not flag:
            continue
        y = gbuffers.mirror(y, axis)
        circles = x[:CIRCLE_CHANNELS].flip(dim)
        x = torch.cat([circles, gbuffers.mirror(x[CIRCLE_CHANNELS:], axis)]) if spheres else circles
    return x, y


class ABDataset(Dataset):
    """AB examples of a split, kept in memory as uint8 ``(N, W, 3W, 4)``; with
    ``max_bytes``, a split larger than that stays on disk and each item is read from its PNG.

    With ``flips`` the dataset is four times as long: item ``k`` is example ``k // 4``
    mirrored by the bits of ``k % 4`` (horizontal, vertical), so an epoch sees every example
    in all four mirrorings.
    """

    def __init__(
        self,
        folder: str | Path,
        manifest: str | Path,
        balls: str | Path,
        variant: str,
        flips: bool = False,
        max_bytes: int | None = None,
    ):
        table = io.read_csv(manifest, ["example", "file"]).sort_values("example")
        self.examples = table["example"].astype(int).tolist()
        self.files = [Path(folder) / f for f in table["file"]]
        first = self.read(0)
        self.images: np.ndarray | None = None
        if max_bytes is None or len(self.files) * first.nbytes <= max_bytes:
            self.images = np.stack([self.read(i) for i in range(len(self.files))])
        self.variant = variant
        self.spheres = uses_spheres(variant)
        self.scenes = read_scenes(balls) if self.spheres else {}
        missing = [e for e in self.examples if self.spheres and e not in self.scenes]
        if missing:
            raise ValueError(f"{balls}: no balls for examples {missing[:5]} of {manifest}")
        self.copies = MIRRORINGS if flips else 1

    def read(self, i: int) -> np.ndarray:
        """Example ``i``'s AB image ``(W, 3W, 4)`` uint8, read from its PNG."""
        image = io.read_png(self.files[i])
        if image.dtype != np.uint8 or image.ndim != 3 or image.shape[-1] != 4:
            raise ValueError(
                f"{self.files[i]}: AB examples must be 8-bit RGBA, got {image.dtype} {image.shape}"
            )
        return image

    def __len__(self) -> int:
        return len(self.files) * self.copies

    def __getitem__(self, k: int) -> tuple[torch.Tensor, torch.Tensor]:
        i, mirroring = divmod(k, self.copies)
        parts = ab.unpack(self.read(i) if self.images is None else self.images[i])
        width = parts["inputs"].shape[-1]
        x = network_inputs(
            self.scenes.get(self.examples[i]), width, self.variant, circles=parts["inputs"]
        )
        y = parts["target"]
        return flip(x * 2 - 1, y * 2 - 1, bool(mirroring & 1), bool(mirroring & 2), self.spheres)
