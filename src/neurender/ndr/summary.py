"""What the NDR data stage made: per-split statistics, the furnace check, a buffer figure."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from neurender import io
from neurender.mitsuba_setup import require_mitsuba
from neurender.ndr.data import split_kind
from neurender.ndr.furnace import furnace
from neurender.plots import save_figure

FURNACE_ROUGHNESS = 0.5


def split_statistics(manifests: dict[str, str]) -> pd.DataFrame:
    """Tidy rows per split: sample count and means of the manifest's numeric columns."""
    rows = []
    for split, path in manifests.items():
        frame = io.read_csv(path, ["sample", "primitives", "coverage", "spp", "seconds"])
        kind, part = split_kind(split)
        values = {"samples": len(frame), **frame.drop(columns="sample").mean(numeric_only=True)}
        rows += [
            {
                "method": "ndr",
                "dataset": kind,
                "model": "data",
                "split": part,
                "metric": k,
                "value": float(v),
            }
            for k, v in values.items()
        ]
    return pd.DataFrame(rows)


def buffers_figure(folder: str, out: str, count: int = 3) -> None:
    """Paper Fig. 1 dataflow for a few test samples: inputs, albedos, shading maps, I_R."""
    files = sorted(Path(folder).glob("*.exr"))[:count]
    names = ("N", "D", "R", "S_D", "S_S", "A_D", "A_S", "I_D", "I_S", "I_R")
    fig, axes = plt.subplots(
        len(files), len(names), figsize=(1.3 * len(names), 1.4 * len(files)), squeeze=False
    )
    for r, path in enumerate(files):
        c = io.read_exr(path)

        def rgb(group: str, suffix: str = "RGB", c: dict = c) -> np.ndarray:
            return np.stack([c[f"{group}.{s}"] for s in suffix], -1)

        mask = c["mask"][..., None]
        images = {
            "N": (rgb("N", "XYZ") + 1) / 2 * mask,
            "D": c["D"],
            "R": c["R"],
            "A_D": rgb("A_D"),
            "A_S": rgb("A_S"),
        }
        for g in ("S_D", "S_S", "I_D", "I_S"):
            images[g] = rgb(g)
        images["I_R"] = images["I_S"] * images["A_S"] + images["I_D"] * images["A_D"]
        for k in ("S_D", "S_S", "I_D", "I_S", "I_R"):  # HDR: Reinhard, gamma 2.2
            images[k] = (images[k] / (1 + images[k])) ** (1 / 2.2)
        for col, name in enumerate(names):
            ax = axes[r, col]
            img = np.clip(images[name], 0, 1)
            ax.imshow(img, cmap="gray" if img.ndim == 2 else None, vmin=0, vmax=1)
            ax.set_title(name if r == 0 else "", fontsize=8)
            ax.axis("off")
    fig.tight_layout()
    save_figure(fig, out)


def summarise(
    manifests: dict[str, str],
    example_folder: str,
    cfg: dict,
    out_csv: str,
    out_furnace: str,
    out_figure: str,
) -> None:
    io.write_csv(out_csv, split_statistics(manifests))
    mi, _ = require_mitsuba(cfg["device"])
    checks = furnace(
        mi, cfg["width"], cfg["furnace_spp"], FURNACE_ROUGHNESS, cfg["coarse_samples"], cfg["seed"]
    )
    io.write_csv(out_furnace, checks)
    buffers_figure(example_folder, out_figure)
