"""Pinhole cameras that Mitsuba and our own ray tracers agree on.

World space is right-handed with +y up. A :class:`Camera` sits at ``origin`` looking at
``target`` with ``fov`` degrees across the (square) image, Mitsuba's ``perspective``
sensor with ``look_at(origin, target, up=+y)``: image row 0 is the top, image column 0 the
camera's left. :func:`pixel_rays` gives exactly the rays through pixel centres that the
sensor traces with a box filter's centre sample, so G-buffers ray-traced by Embree line up
with Mitsuba's renders pixel for pixel.
"""

from __future__ import annotations

import dataclasses
import math
from types import ModuleType

import numpy as np


@dataclasses.dataclass(frozen=True)
class Camera:
    """``origin`` and ``target`` ``(3,)`` in world units, ``fov`` in degrees."""

    origin: tuple[float, float, float]
    target: tuple[float, float, float]
    fov: float


def direction(azimuth_deg: float, elevation_deg: float) -> np.ndarray:
    """Unit vector ``(3,)``: azimuth about +y from +z towards +x, elevation towards +y."""
    a, e = math.radians(azimuth_deg), math.radians(elevation_deg)
    return np.array([math.sin(a) * math.cos(e), math.sin(e), math.cos(a) * math.cos(e)])


def camera_basis(camera: Camera) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mitsuba's ``look_at`` frame: ``(left, up, forward)`` unit vectors ``(3,)`` each."""
    forward = np.subtract(camera.target, camera.origin)
    forward = forward / np.linalg.norm(forward)
    left = np.cross([0.0, 1.0, 0.0], forward)
    left /= np.linalg.norm(left)
    return left, np.cross(forward, left), forward


def pixel_rays(camera: Camera, width: int) -> np.ndarray:
    """Unit ray directions ``(W, W, 3)`` through pixel centres, row 0 at the top, matching
    Mitsuba's ``perspective`` sensor (image left = camera +x = ``left``)."""
    left, up, forward = camera_basis(camera)
    tan = math.tan(math.radians(camera.fov) / 2)
    c = 1 - (np.arange(width) + 0.5) / width * 2  # +1 at the left / top edge
    y, x = np.meshgrid(c, c, indexing="ij")
    d = forward + tan * (x[..., None] * left + y[..., None] * up)
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def look_at(mi: ModuleType, camera: Camera):
    """The camera's ``to_world`` transform for Mitsuba."""
    return mi.ScalarTransform4f().look_at(origin=camera.origin, target=camera.target, up=[0, 1, 0])


def sensor(
    mi: ModuleType,
    camera: Camera,
    width: int,
    spp: int,
    alpha: bool = True,
    sample_border: bool = False,
) -> dict:
    """Mitsuba ``perspective`` sensor dict: a ``width x width`` HDR film with a box filter
    (a fourth, coverage channel with ``alpha``) and an ``independent`` sampler at ``spp``.
    ``sample_border`` is what the projective integrators want for silhouette gradients."""
    return {
        "type": "perspective",
        "fov": camera.fov,
        "to_world": look_at(mi, camera),
        "film": {
            "type": "hdrfilm",
            "width": width,
            "height": width,
            "rfilter": {"type": "box"},
            "pixel_format": "rgba" if alpha else "rgb",
            "sample_border": sample_border,
        },
        "sampler": {"type": "independent", "sample_count": spp},
    }
