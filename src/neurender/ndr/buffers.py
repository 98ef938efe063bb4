"""The files of an NDR split and loading them as tensors.

A split is a folder of samples, a manifest CSV (``sample, file, ...``: one row per sample,
see :func:`neurender.ndr.data.make_sample`) and a lighting CSV.

One sample is a float32 OpenEXR with named channels (rows top first, linear values,
view-space vectors):

``N.X N.Y N.Z`` normals, ``R`` roughness, ``D`` depth, ``A_D.{R,G,B}`` and
``A_S.{R,G,B}`` albedos, ``S_D.*`` and ``S_S.*`` coarse shading, ``I_D.*`` and ``I_S.*``
ray-traced shading maps, ``mask`` (pixel centre on the object). Test samples add
``I_D_noisy.*`` and ``I_S_noisy.*``: an independent render at the *training* sample count,
for the noise floor (the test's ``I_D``/``I_S`` use ``reference_spp``).

The lighting CSV is tidy, ``sample, coefficient, channel, value``: the 5-band SH (25 x
RGB) of each sample's map (see :mod:`neurender.ndr.environments`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import torch
import torch.nn.functional as F
from torch.utils.data import Dataset

from neurender import io
from neurender.ndr.environments import SH_FEATURES

RGB = ("R", "G", "B")
XYZ = ("X", "Y", "Z")
BUFFERS = {  # EXR channel groups and their channel suffixes
    "N": XYZ,
    "R": (),
    "D": (),
    "A_D": RGB,
    "A_S": RGB,
    "S_D": RGB,
    "S_S": RGB,
    "I_D": RGB,
    "I_S": RGB,
    "mask": (),
}
NOISY = {"I_D_noisy": RGB, "I_S_noisy": RGB}


def _suffixes(group: str) -> tuple[str, ...]:
    return BUFFERS.get(group) or NOISY.get(group, ())


def channels(group: str, image: np.ndarray) -> dict[str, np.ndarray]:
    """EXR channels of one buffer group: ``(H, W)`` or ``(H, W, C)`` -> name -> ``(H, W)``."""
    suffixes = _suffixes(group)
    if not suffixes:
        return {group: image}
    return {f"{group}.{s}": image[..., i] for i, s in enumerate(suffixes)}


def channel_count(group: str) -> int:
    """Channels of a buffer group as a tensor: 3 for ``N`` or ``A_D``, 1 for ``D``."""
    return max(1, len(_suffixes(group)))


def lighting_rows(sample: int, light: np.ndarray) -> list[dict]:
    """Tidy lighting rows of one sample's SH vector ``(75,)`` (coefficient-major)."""
    return [
        {"sample": sample, "coefficient": k // 3, "channel": RGB[k % 3], "value": float(value)}
        for k, value in enumerate(light)
    ]


def read_lighting(path: str | Path, samples: pd.Series) -> np.ndarray:
    """The SH vectors ``(N, 75)`` float32 of ``samples`` (in that order) from a lighting CSV."""
    sh = io.read_csv(path, ["sample", "coefficient", "channel", "value"])
    sh = sh.assign(k=sh["coefficient"] * 3 + sh["channel"].map({c: i for i, c in enumerate(RGB)}))
    table = sh.pivot(index="sample", columns="k", values="value").loc[samples]
    if table.shape[1] != SH_FEATURES or table.isna().any().any():
        raise ValueError(f"{path}: expected {SH_FEATURES} SH values for every sample")
    return table.to_numpy(np.float32)


def light_features(sh: np.ndarray | torch.Tensor) -> torch.Tensor:
    """SH vectors ``(..., 75)`` as the networks take them: ``sign(c) log(1 + |c|)`` (this
    compresses the sun's range; the paper does not say how it scales its light input)."""
    light = torch.tensor(np.asarray(sh, np.float32))
    return torch.sign(light) * torch.log1p(light.abs())


def erode(mask: torch.Tensor, pixels: int) -> torch.Tensor:
    """A ``(N, 1, H, W)`` {0, 1} mask shrunk by ``pixels`` (a square neighbourhood)."""
    if pixels <= 0:
        return mask
    return 1 - F.max_pool2d(1 - mask, 2 * pixels + 1, stride=1, padding=pixels)


def stack_samples(samples: list[dict[str, np.ndarray]], erosion: int) -> dict[str, torch.Tensor]:
    """EXR channel dicts of one kind to float32 buffer tensors ``(N, C, H, W)`` keyed by
    group, the mask eroded by ``erosion`` pixels."""
    first = samples[0]
    groups = [g for g in {**BUFFERS, **NOISY} if any(c.split(".")[0] == g for c in first)]
    buffers = {}
    for g in groups:
        suffixes = _suffixes(g)
        keys = [f"{g}.{s}" for s in suffixes] if suffixes else [g]
        stacked = np.stack([np.stack([c[k] for k in keys]) for c in samples])
        buffers[g] = torch.from_numpy(stacked.astype(np.float32))
    buffers["mask"] = erode(buffers["mask"], erosion)
    return buffers


class NDRDataset(Dataset):
    """A split of samples. Items are dicts of float32 tensors:

    ``N`` (3, H, W) in [-1, 1], ``R`` (1), ``D`` (1), ``A_D``/``A_S`` (3) in [0, 1],
    ``S_D``/``S_S``/``I_D``/``I_S`` (3) linear HDR, ``mask`` (1) eroded by ``erosion`` px,
    ``light`` (75) the SH features (:func:`light_features`), and ``I_D_noisy``,
    ``I_S_noisy`` on test splits. ``buffers`` holds the whole split ``(N, C, H, W)``, or
    its first ``count`` samples; with ``max_bytes``, a split larger than that stays on disk
    (``buffers`` is None) and each item is read from its file.
    """

    def __init__(
        self,
        folder: str | Path,
        manifest: str | Path,
        lighting: str | Path,
        erosion: int,
        count: int | None = None,
        max_bytes: int | None = None,
    ):
        frame = io.read_csv(manifest, ["sample", "file"]).sort_values("sample").head(count)
        self.light = light_features(read_lighting(lighting, frame["sample"]))
        self.files = [Path(folder) / name for name in frame["file"]]
        self.erosion = erosion
        self.buffers: dict[str, torch.Tensor] | None = None
        if max_bytes is None or len(self.files) * self.sample_bytes() <= max_bytes:
            self.buffers = stack_samples([io.read_exr(f) for f in self.files], erosion)

    @classmethod
    def from_files(
        cls,
        files: dict[str, str],
        erosion: int,
        count: int | None = None,
        max_bytes: int | None = None,
    ) -> NDRDataset:
        """A split (its first ``count`` samples) from its ``dir``, ``manifest`` and
        ``lighting`` files."""
        return cls(files["dir"], files["manifest"], files["lighting"], erosion, count, max_bytes)

    def read(self, i: int) -> dict[str, torch.Tensor]:
        """Sample ``i``'s buffers ``(C, H, W)``, read from its file."""
        buffers = stack_samples([io.read_exr(self.files[i])], self.erosion)
        return {g: v[0] for g, v in buffers.items()}

    def sample_bytes(self) -> int:
        """The memory one sample's buffers take (the first sample's)."""
        return sum(v.numel() * v.element_size() for v in self.read(0).values())

    def __len__(self) -> int:
        return len(self.light)

    def __getitem__(self, i: int) -> dict[str, torch.Tensor]:
        if self.buffers is None:
            return {"light": self.light[i], **self.read(i)}
        return {"light": self.light[i], **{g: v[i] for g, v in self.buffers.items()}}
