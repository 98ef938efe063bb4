"""Files of the DeepPRT data stage (see docs/methods/prt.md, "Data stage").

* ``probes/{probe}_sh.csv``: a probe's SH projection, tidy rows ``k, l, m, channel, value``
  (channels R, G, B; the probe itself is an RGB lat-long EXR, :mod:`neurender.lights`).
* ``{object}/sequence.npz``: per split ``{split}_positions`` ``(F, n, n, 3)`` and
  ``{split}_params`` ``(F, P)`` shape parameters; ``test_extrapolated`` ``(F,)``, ``kind``.
* ``{object}/{split}/frame_XXXX.exr``: channels ``P.x P.y P.z N.x N.y N.z`` (float32),
  ``T.00 ... T.{K-1}`` diffuse transfer and ``G.r.00 ... G.b.{K-1}`` glossy transferred
  radiance (float16), ``K = n_bands^2``; ``{split}_manifest.csv`` one row per frame.

A :class:`Split` is one split of one object loaded in memory.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pandas as pd

from neurender import io
from neurender.prt import MATERIALS

COLOURS = ("r", "g", "b")


def channel_names(n_bands: int) -> dict[str, list[str]]:
    """EXR channel names: positions, normals, diffuse transfer, glossy radiance."""
    k = n_bands * n_bands
    return {
        "P": [f"P.{a}" for a in "xyz"],
        "N": [f"N.{a}" for a in "xyz"],
        "T": [f"T.{j:02d}" for j in range(k)],
        "G": [f"G.{c}.{j:02d}" for c in COLOURS for j in range(k)],
    }


def write_frame(
    path: str | Path,
    positions: np.ndarray,
    normals: np.ndarray,
    diffuse: np.ndarray,
    glossy: np.ndarray,
    n_bands: int,
) -> None:
    """One frame: P, N ``(n, n, 3)``, diffuse ``(n, n, K)``, glossy ``(n, n, 3, K)``."""
    names = channel_names(n_bands)
    channels = {}
    channels.update(zip(names["P"], np.moveaxis(positions, -1, 0), strict=True))
    channels.update(zip(names["N"], np.moveaxis(normals, -1, 0), strict=True))
    channels.update(zip(names["T"], np.moveaxis(diffuse.astype(np.float16), -1, 0), strict=True))
    g = glossy.reshape(*glossy.shape[:2], -1).astype(np.float16)  # (n, n, 3 K), colour-major
    channels.update(zip(names["G"], np.moveaxis(g, -1, 0), strict=True))
    io.write_exr(path, channels)


def read_frame(path: str | Path, n_bands: int) -> dict[str, np.ndarray]:
    """One frame EXR as arrays: P, N ``(n, n, 3)``, T ``(n, n, K)``, G ``(n, n, 3, K)`` float32."""
    names = channel_names(n_bands)
    ch = io.read_exr(path, [c for group in names.values() for c in group])
    stack = {
        key: np.stack([ch[c].astype(np.float32) for c in cols], -1) for key, cols in names.items()
    }
    n = stack["P"].shape[0]
    stack["G"] = stack["G"].reshape(n, n, 3, n_bands * n_bands)
    return stack


@dataclasses.dataclass
class Split:
    """One split of one object, loaded in memory.

    Attributes:
        positions, normals: ``(F, n, n, 3)`` float32.
        diffuse: ``(F, n, n, K)``; glossy: ``(F, n, n, 3, K)`` float32.
        params: ``(F, P)`` shape parameters from the sequence file.
    """

    positions: np.ndarray
    normals: np.ndarray
    diffuse: np.ndarray
    glossy: np.ndarray
    params: np.ndarray

    def targets(self, material: str) -> np.ndarray:
        """``(F, C, n, n)`` target images of a material."""
        if material == "diffuse":
            t = self.diffuse
        elif material == "glossy":
            t = self.glossy.reshape(*self.glossy.shape[:3], -1)
        else:
            raise ValueError(f"material {material!r}: expected one of {MATERIALS}")
        return np.ascontiguousarray(np.moveaxis(t, -1, 1))


def load_split(
    frames_dir: str | Path,
    manifest: str | Path,
    params: np.ndarray,
    n_bands: int,
    first: int | None = None,
) -> Split:
    """Read the frame EXRs listed in a split's manifest, in frame order: every one, or the
    ``first`` ones (all if the split has fewer)."""
    files = io.read_csv(manifest, ["frame", "file"]).sort_values("frame")["file"].tolist()
    if len(files) != len(params):
        raise ValueError(f"{manifest} lists {len(files)} frames but the sequence has {len(params)}")
    frames = [read_frame(Path(frames_dir) / f, n_bands) for f in files[:first]]
    stacked = (np.stack([fr[k] for fr in frames]) for k in ("P", "N", "T", "G"))
    return Split(*stacked, params=params[:first])


def sh_light_table(coeffs: np.ndarray) -> pd.DataFrame:
    """Tidy rows ``k, l, m, channel, value`` of SH light coefficients ``(K, 3)`` (R, G, B)."""
    rows = [
        {
            "k": k,
            "l": int(np.sqrt(k)),
            "m": k - int(np.sqrt(k)) * (int(np.sqrt(k)) + 1),
            "channel": c,
            "value": coeffs[k, i],
        }
        for k in range(coeffs.shape[0])
        for i, c in enumerate("RGB")
    ]
    return pd.DataFrame(rows)


def read_sh_light(path: str | Path, n_bands: int | None = None) -> np.ndarray:
    """SH light ``(K, 3)`` from a probe's tidy CSV; its first ``n_bands^2`` coefficients
    when ``n_bands`` is given."""
    frame = io.read_csv(path, ["k", "channel", "value"])
    wide = frame.pivot(index="k", columns="channel", values="value")
    light = wide[["R", "G", "B"]].to_numpy(np.float64)
    return light if n_bands is None else light[: n_bands**2]


def ray_offset(positions: np.ndarray, relative: float) -> float:
    """Origin offset in world units: ``relative`` times the rest shape's bounding-box diagonal."""
    p = positions.reshape(-1, 3)
    return relative * float(np.linalg.norm(p.max(0) - p.min(0)))


def split_frames(
    inputs: dict, seq: dict, split: str, n_bands: int, first: int | None = None
) -> Split:
    """A split's frames (its ``first`` ones, all if ``None``) from a job's inputs
    (``{split}_dir``, ``{split}_manifest``) and its sequence's deformation parameters."""
    return load_split(
        inputs[f"{split}_dir"], inputs[f"{split}_manifest"], seq[f"{split}_params"], n_bands, first
    )
