"""Relighting one unseen object (paper Fig. 3 (d)): the same test sample under its map
turned about +y, rendered by Mitsuba and by NDR from the same buffers and the new SH."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
import torch

from neurender import io, train
from neurender.ndr import data
from neurender.ndr import model as ndr_model
from neurender.ndr.evaluate import display, score
from neurender.ndr.model import compose, shading_input
from neurender.plots import save_figure


def relight(
    mi,
    cfg: dict,
    checkpoint: str,
    sample: int,
    turns: int,
    threads: int,
    out_csv: str,
    out_figure: str,
) -> None:
    """Render test ``sample`` under ``turns`` evenly spaced rotations of its map; write the
    DSSIM/L2 of NDR and of the shading input per rotation and a figure."""
    width = 2 * cfg["environment_height"]
    shifts = [round(k * width / turns) for k in range(turns)]
    made = [data.make_sample(cfg, "test", sample, mi, env_shift=s) for s in shifts]
    buffers = ndr_model.stack_samples([m[0] for m in made], cfg["mask_erosion"])
    buffers["light"] = ndr_model.light_features(np.stack([m[1] for m in made]))
    device = train.resolve_device(cfg["device"], threads)
    model = ndr_model.load_model(checkpoint, device)
    with torch.no_grad():
        pred = {k: v.cpu() for k, v in model({k: v.to(device) for k, v in buffers.items()}).items()}
    truth = compose(buffers["I_D"], buffers["I_S"], buffers)
    coarse = shading_input(buffers)
    rows = []
    for method, images in (("ndr", pred), ("shading_input", coarse)):
        for metric, values in score(images, truth, buffers["mask"]).items():
            if metric.endswith("I_R"):
                rows += [
                    {
                        "method": "ndr",
                        "dataset": "complex",
                        "model": method,
                        "split": f"relit test sample {sample}",
                        "metric": metric,
                        "rotation_deg": 360.0 * s / width,
                        "value": float(v),
                    }
                    for s, v in zip(shifts, values, strict=True)
                ]
    frame = pd.DataFrame(rows)
    io.write_csv(out_csv, frame)
    dssim = frame[frame.metric == "dssim_I_R"].set_index(["model", "rotation_deg"])["value"]

    fig, axes = plt.subplots(3, turns, figsize=(1.7 * turns, 5.4), squeeze=False)
    for k, shift in enumerate(shifts):
        deg = 360.0 * shift / width
        panels = (
            (f"Mitsuba, map +{deg:.0f} deg", truth["I_R"][k]),
            (f"NDR (DSSIM {dssim[('ndr', deg)]:.3f})", pred["I_R"][k]),
            (f"shading input ({dssim[('shading_input', deg)]:.3f})", coarse["I_R"][k]),
        )
        for r, (title, image) in enumerate(panels):
            axes[r, k].imshow(np.clip(display(image), 0, 1))
            axes[r, k].set_title(title, fontsize=7)
            axes[r, k].axis("off")
    fig.tight_layout()
    save_figure(fig, out_figure)
