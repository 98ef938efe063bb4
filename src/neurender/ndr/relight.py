"""Relighting one unseen object (paper Fig. 3 (d)): the same test sample under its map
turned about +y, rendered by Mitsuba and by NDR from the same buffers and the new SH."""

from __future__ import annotations

import numpy as np
import pandas as pd
import torch

from neurender.ndr import data
from neurender.ndr.buffers import light_features, stack_samples
from neurender.ndr.evaluate import score
from neurender.ndr.model import SHADING_INPUT, NDRModel, compose, shading_input

#: Columns of the relighting table: tidy, with the map's rotation beside the metric.
COLUMNS = ["method", "dataset", "model", "split", "metric", "rotation_deg", "value"]


def rotations(environment_height: int, turns: int) -> tuple[list[int], list[float]]:
    """``turns`` evenly spaced map rotations: whole pixel columns of the lat-long map
    (``2 environment_height`` wide) and the same in degrees."""
    width = 2 * environment_height
    shifts = [round(k * width / turns) for k in range(turns)]
    return shifts, [360.0 * s / width for s in shifts]


def relit_buffers(mi, cfg: dict, sample: int, shifts: list[int]) -> dict[str, torch.Tensor]:
    """Test ``sample`` rendered once per map rotation ``shifts`` (pixel columns): buffer
    tensors ``(T, C, H, W)`` and ``light`` ``(T, 75)`` (see :mod:`neurender.ndr.buffers`)."""
    made = [data.make_sample(cfg, "test", sample, mi, env_shift=s) for s in shifts]
    buffers = stack_samples([m[0] for m in made], cfg["mask_erosion"])
    buffers["light"] = light_features(np.stack([m[1] for m in made]))
    return buffers


@torch.no_grad()
def relight(model: NDRModel, buffers: dict[str, torch.Tensor], device: torch.device) -> dict:
    """Ground truth, NDR and the shading input's HDR ``{I_D, I_S, I_R}`` of relit buffers."""
    pred = model({k: v.to(device) for k, v in buffers.items()})
    return {
        "truth": compose(buffers["I_D"], buffers["I_S"], buffers),
        "ndr": {k: v.cpu() for k, v in pred.items()},
        SHADING_INPUT: shading_input(buffers),
    }


def relight_table(
    images: dict, mask: torch.Tensor, sample: int, degrees: list[float]
) -> pd.DataFrame:
    """DSSIM and L2 of ``I_R`` of NDR and of the shading input per rotation (``degrees``)."""
    rows = []
    for method in ("ndr", SHADING_INPUT):
        for metric, values in score(images[method], images["truth"], mask).items():
            if metric.endswith("I_R"):
                rows += [
                    {
                        "method": "ndr",
                        "dataset": "complex",
                        "model": method,
                        "split": f"relit test sample {sample}",
                        "metric": metric,
                        "rotation_deg": deg,
                        "value": float(v),
                    }
                    for deg, v in zip(degrees, values, strict=True)
                ]
    return pd.DataFrame(rows, columns=COLUMNS)
