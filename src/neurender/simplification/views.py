"""Random views and point lights for optimisation and evaluation (paper eq. 1).

A :class:`View` is a camera (:class:`neurender.camera.Camera`) looking at the origin from
``distance`` along a direction given by azimuth (about +y, 0 = looking from +z) and
elevation, plus a point light at ``light_distance`` in a direction within ``light_cone``
degrees of the camera's. Training and test views come from independent seeds, so test
views are never optimised against.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pandas as pd

from neurender.camera import Camera, direction
from neurender.rng import stable_seed
from neurender.simplification import SEED_SALT


@dataclasses.dataclass(frozen=True)
class View(Camera):
    """A camera with the point light's ``light`` position (world space) and the camera's
    ``azimuth`` and ``elevation`` in degrees."""

    light: tuple[float, float, float]
    azimuth: float
    elevation: float


def sample_views(
    count: int,
    seed: int,
    split: str,
    distance: float,
    fov: float,
    azimuth: tuple[float, float],
    elevation: tuple[float, float],
    light_distance: float,
    light_cone: float,
) -> list[View]:
    """``count`` views with azimuth and elevation uniform in the given degree ranges."""
    rng = np.random.default_rng(stable_seed(seed, SEED_SALT, "views", split))
    views = []
    for _ in range(count):
        az, el = rng.uniform(*azimuth), rng.uniform(*elevation)
        eye = direction(az, el)
        # A light direction uniform in a cone around the eye direction.
        cos_max = math.cos(math.radians(light_cone))
        cos_t = rng.uniform(cos_max, 1.0)
        phi = rng.uniform(0, 2 * math.pi)
        helper = np.array([0.0, 1.0, 0.0]) if abs(eye[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
        s = np.cross(helper, eye)
        s /= np.linalg.norm(s)
        t = np.cross(eye, s)
        sin_t = math.sqrt(1 - cos_t**2)
        light = eye * cos_t + (s * math.cos(phi) + t * math.sin(phi)) * sin_t
        views.append(
            View(
                origin=tuple(map(float, eye * distance)),
                target=(0.0, 0.0, 0.0),
                fov=fov,
                light=tuple(map(float, light * light_distance)),
                azimuth=float(az),
                elevation=float(el),
            )
        )
    return views


def views_frame(views: list[View]) -> pd.DataFrame:
    """One row per view (for the CSV written beside the reference images)."""
    rows = []
    for i, v in enumerate(views):
        rows.append(
            {
                "view": i,
                **{f"origin_{a}": c for a, c in zip("xyz", v.origin, strict=True)},
                **{f"light_{a}": c for a, c in zip("xyz", v.light, strict=True)},
                "fov": v.fov,
                "azimuth": v.azimuth,
                "elevation": v.elevation,
            }
        )
    return pd.DataFrame(rows)


def views_from_frame(frame: pd.DataFrame) -> list[View]:
    """Inverse of :func:`views_frame`."""
    return [
        View(
            origin=(float(r.origin_x), float(r.origin_y), float(r.origin_z)),
            target=(0.0, 0.0, 0.0),
            fov=float(r.fov),
            light=(float(r.light_x), float(r.light_y), float(r.light_z)),
            azimuth=float(r.azimuth),
            elevation=float(r.elevation),
        )
        for r in frame.itertuples()
    ]
