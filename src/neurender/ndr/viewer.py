"""The report's interactive NDR view: one unseen test sample under its map turned about +y
in :data:`neurender.viewer_data.TURNS` steps, by Mitsuba (the reference), NDR and the
shading input (:mod:`neurender.ndr.relight`), with a slider over the turns.

See :mod:`neurender.viewer_data` (kind ``frames``). Images are ``I_R`` (linear HDR
radiance) Reinhard tone-mapped with gamma 2.2 (:func:`neurender.display.tonemap`), one
exposure for every turn, as uint8 RGB.
"""

from __future__ import annotations

import torch

from neurender import io, viewer_data
from neurender.display import tonemap
from neurender.ndr.model import SHADING_INPUT

#: Panels left to right: label -> key of :func:`neurender.ndr.relight.relight`'s images.
PANELS = {"Mitsuba (reference)": "truth", "NDR": "ndr", "shading input": SHADING_INPUT}


def display_images(radiance: torch.Tensor) -> list:
    """``(T, 3, H, W)`` HDR radiance to ``T`` uint8 ``(H, W, 3)`` display images."""
    return [io.to_uint8(tonemap(x).permute(1, 2, 0).numpy()) for x in radiance]


def relight_view(images: dict, degrees: list[float]) -> dict:
    """The ``frames`` viewer data of relit images: ``images`` maps each key of
    :data:`PANELS` to ``{"I_R": (T, 3, H, W)}``, one image per map turn ``degrees``."""
    width = images["truth"]["I_R"].shape[-1]
    frames = {label: display_images(images[key]["I_R"]) for label, key in PANELS.items()}
    return viewer_data.frames_data(
        frames,
        "turn the map about +y",
        viewer_data.display_scale(width),
        steps=[f"{d:.0f} deg" for d in degrees],
    )
