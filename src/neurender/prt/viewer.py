"""The report's interactive DeepPRT view: one test frame as a mesh with each model's
per-vertex diffuse transfer, and light probes turned about +y, for the page to relight.

See :mod:`neurender.viewer_data` (kind ``prt``): the page shades ``1/pi sum_j l_j t_j`` per
vertex and colour with the chosen probe's rotated SH light.
"""

from __future__ import annotations

import math

import numpy as np

from neurender import sh, viewer_data
from neurender.geometry import grid_faces
from neurender.prt.frames import Split

#: Turns of the light about +y offered by the page's slider (degrees apart: 360 / TURNS).
TURNS = viewer_data.TURNS


def prt_view(
    data: Split,
    frame: int,
    predictions: dict[str, np.ndarray],
    probes: dict[str, np.ndarray],
    n_bands: int,
) -> dict:
    """The ``prt`` viewer data of ``frame`` of a split.

    Args:
        predictions: model name -> ``(F, K, n, n)`` predicted diffuse transfer.
        probes: probe name -> ``(K, 3)`` SH light.
    """
    n = data.positions.shape[1]
    k = n_bands * n_bands
    transfer = {"ground truth": data.diffuse[frame].reshape(n * n, k)}
    transfer |= {m: np.moveaxis(p[frame], 0, -1).reshape(n * n, k) for m, p in predictions.items()}
    angles = [360.0 * t / TURNS for t in range(TURNS)]
    lights = {
        name: np.stack([sh.rotation_about_y(math.radians(a), n_bands) @ c for a in angles])
        for name, c in probes.items()
    }
    return {
        "positions": viewer_data.b64_array(data.positions[frame].reshape(-1, 3), "f4"),
        "indices": viewer_data.b64_array(grid_faces(n), "u4"),
        "coefficients": k,
        "transfer": {m: viewer_data.b64_array(t, "f4") for m, t in transfer.items()},
        "probes": {
            name: {"turns": angles, "lights": viewer_data.b64_array(light, "f4")}
            for name, light in lights.items()
        },
    }
