"""Your metaball scenes: a CSV of balls, rendered by every trained network and by the ray
marcher, scored like the held-out test scenes.

The file has one row per ball and the columns :data:`COLUMNS`: ``scene`` (any label; the
rows of one scene need not be adjacent), the centre ``x, y, z`` in the view space of
:mod:`neurender.metaballs.scenes` (camera at the origin looking along +z, x right, y up;
the networks saw centres 8 to 24 units deep, within 0.9 of the 30-degree field of view),
the size ``radius`` (> 0, world units; an isolated ball is a sphere of that radius) and the
colour ``r, g, b`` (linear, in [0, 1]). Other columns are ignored.

What the camera sees is checked too: a scene whose surface holds the camera is refused when
the file is read (:func:`neurender.metaballs.scene_file.camera_inside`); a scene with
nothing of the surface in view (``empty_frame`` 1: no scores, see
:mod:`neurender.metaballs.evaluate`) or whose surface the near plane cuts on more than
:data:`NEAR_PLANE_WARN` of the frame (``near_plane_cut``, a flat wall at the near depth
there) is scored, marked in the table and warned about (:func:`view_notes`).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping

import numpy as np
import pandas as pd
import torch

from neurender.metaball import INVERSE_SQUARE, THRESHOLD, Kernel, Scene, field
from neurender.metaballs import EMPTY_FRAME, ab, inputs, raymarch, scenes
from neurender.metaballs.evaluate import Showcase, baselines, example_metrics
from neurender.metaballs.renderer import MetaballRenderer
from neurender.metaballs.scene_file import NUMBERS
from neurender.tables import tidy_rows

log = logging.getLogger(__name__)

#: The ``dataset`` and ``split`` label of the rows.
DATASET = "your scenes"
#: The row of each scene's share of pixels whose ray starts inside the surface, and the
#: share from which a scene is warned about (a few pixels at a ball's edge are harmless).
NEAR_PLANE_CUT = "near_plane_cut"
NEAR_PLANE_WARN = 0.02


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


def near_plane_cut(scene: Scene, width: int) -> float:
    """Share of the ``width x width`` pixels whose ray starts inside the surface: the field
    at distance ``MIN_DEPTH`` along it, where the ray marcher starts, at least
    ``THRESHOLD``, so that the target shows there a flat wall at normalised depth 0 (the
    marcher's own first test, in the scene's dtype)."""
    rays = scenes.pixel_rays(width, scene.centres.dtype, scene.centres.device).reshape(-1, 3)
    inside = field(scenes.MIN_DEPTH * rays, scene)[0] >= THRESHOLD
    return float(inside.double().mean())


def view_notes(frame: pd.DataFrame) -> list[str]:
    """Warnings, one per scene of :func:`score_user_scenes`'s rows, for a frame with
    nothing of the surface in view (``empty_frame`` 1) or whose surface the near plane cuts
    on more than :data:`NEAR_PLANE_WARN` of the pixels."""
    notes = []
    for scene, rows in frame.groupby("scene", sort=False):
        values = rows.groupby("metric")["value"].max()
        if values.get(EMPTY_FRAME, 0) > 0:
            notes.append(
                f"scene {scene!r}: nothing of the surface is in view (the ray-marched frame is "
                "empty: balls too small, too far or outside the field of view); not scored, "
                f"marked {EMPTY_FRAME} = 1"
            )
        cut = values.get(NEAR_PLANE_CUT, 0.0)
        if cut > NEAR_PLANE_WARN:
            notes.append(
                f"scene {scene!r}: the near plane (depth {scenes.MIN_DEPTH:g}) cuts the surface "
                f"on {cut:.0%} of the pixels, where the target is a flat wall (balls reaching "
                f"nearer than depth {scenes.MIN_DEPTH:g}); scored, marked {NEAR_PLANE_CUT} = "
                f"{cut:.3g}"
            )
    return notes


def to_scenes(balls: pd.DataFrame, kernel: Kernel = INVERSE_SQUARE) -> dict[str, Scene]:
    """Scene label to its float32 :class:`~neurender.metaball.Scene` of the field
    ``kernel``, in order of first appearance."""
    out = {}
    for scene, rows in balls.groupby("scene", sort=False):
        values = torch.tensor(rows[list(NUMBERS)].to_numpy(), dtype=torch.float32)
        out[str(scene)] = Scene(values[:, :3], values[:, 3], values[:, 4:], kernel)
    return out


def score_user_scenes(
    scene_of: Mapping[str, Scene], renderers: Mapping[str, MetaballRenderer], width: int
) -> tuple[pd.DataFrame, dict[str, Showcase]]:
    """Every renderer's and baseline's metrics on every scene against the ray marcher, as
    tidy rows keyed by ``scene, balls`` (the metrics of
    :func:`neurender.metaballs.evaluate.example_metrics`, inputs and target through the
    8-bit AB format as the test scenes, then :data:`NEAR_PLANE_CUT`); and each scene's
    circles, ray-marched stack and predictions for the figure."""
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
        cut = near_plane_cut(scene, width)
        for model, pred in preds.items():
            rows += tidy_rows(
                "metaballs",
                DATASET,
                model,
                DATASET,
                {**example_metrics(pred, truth), NEAR_PLANE_CUT: cut},
                scene=label,
                balls=len(scene),
            )
        shown[label] = Showcase(len(scene), circles, truth, preds)
    return pd.DataFrame(rows), shown
