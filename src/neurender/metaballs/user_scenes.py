"""Your metaball scenes: a CSV of balls, rendered by every trained network and by the ray
marcher, scored like the held-out test scenes.

The file has one row per ball and the columns :data:`COLUMNS`: ``scene`` (any label; the
rows of one scene need not be adjacent), the centre ``x, y, z`` in the view space of
:mod:`neurender.metaballs.scenes` (camera at the origin looking along +z, x right, y up;
the networks saw centres 8 to 24 units deep, within 0.9 of the 30-degree field of view),
the size ``radius`` (> 0, world units; an isolated ball is a sphere of that radius) and the
colour ``r, g, b`` (linear, in [0, 1]). Other columns are ignored.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping

import numpy as np
import pandas as pd
import torch

from neurender.metaball import Scene
from neurender.metaballs import ab, inputs, raymarch, scenes
from neurender.metaballs.evaluate import Showcase, baselines, example_metrics
from neurender.metaballs.renderer import MetaballRenderer
from neurender.metaballs.scene_file import NUMBERS
from neurender.tables import tidy_rows

log = logging.getLogger(__name__)

#: The ``dataset`` and ``split`` label of the rows.
DATASET = "your scenes"


def outside_training(balls: pd.DataFrame) -> list[str]:
    """Warnings, one per scene, for balls outside what the networks were trained on:
    centre depth outside [MIN_DEPTH, MAX_DEPTH] or centre outside the field of view."""
    tan = math.tan(math.radians(scenes.FOV_DEG))
    depth = np.sqrt(balls["x"] ** 2 + balls["y"] ** 2 + balls["z"] ** 2)
    out_of_depth = (depth < scenes.MIN_DEPTH) | (depth > scenes.MAX_DEPTH)
    out_of_view = (balls["x"].abs() > tan * balls["z"]) | (balls["y"].abs() > tan * balls["z"])
    notes = []
    for scene, rows in balls.assign(d=out_of_depth, v=out_of_view).groupby("scene", sort=False):
        if rows["d"].any() or rows["v"].any():
            notes.append(
                f"scene {scene}: {int(rows['d'].sum())} ball(s) outside depths "
                f"{scenes.MIN_DEPTH:g}-{scenes.MAX_DEPTH:g}, {int(rows['v'].sum())} outside the "
                "field of view (the networks never saw such balls)"
            )
    return notes


def to_scenes(balls: pd.DataFrame) -> dict[str, Scene]:
    """Scene label to its float32 :class:`~neurender.metaball.Scene`, in order of first
    appearance."""
    out = {}
    for scene, rows in balls.groupby("scene", sort=False):
        values = torch.tensor(rows[list(NUMBERS)].to_numpy(), dtype=torch.float32)
        out[str(scene)] = Scene(values[:, :3], values[:, 3], values[:, 4:])
    return out


def score_user_scenes(
    scene_of: Mapping[str, Scene], renderers: Mapping[str, MetaballRenderer], width: int
) -> tuple[pd.DataFrame, dict[str, Showcase]]:
    """Every renderer's and baseline's metrics on every scene against the ray marcher, as
    tidy rows keyed by ``scene, balls`` (the metrics of
    :func:`neurender.metaballs.evaluate.example_metrics`, inputs and target through the
    8-bit AB format as the test scenes); and each scene's circles, ray-marched stack and
    predictions for the figure."""
    rows, shown = [], {}
    for label, scene in scene_of.items():
        # Through the AB format, as the test scenes are: 8-bit circles and target.
        packed = ab.unpack(
            ab.pack(
                inputs.draw_inputs(scene, width), raymarch.render_gbuffers(scene, width).stack()
            )
        )
        circles, truth = packed["inputs"], packed["target"]
        preds = {name: r(r.inputs(scene, circles)[None])[0] for name, r in renderers.items()}
        preds.update(baselines(scene, width))
        for model, pred in preds.items():
            rows += tidy_rows(
                "metaballs",
                DATASET,
                model,
                DATASET,
                example_metrics(pred, truth),
                scene=label,
                balls=len(scene),
            )
        shown[label] = Showcase(len(scene), circles, truth, preds)
    return pd.DataFrame(rows), shown
