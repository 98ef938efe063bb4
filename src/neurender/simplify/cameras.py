"""Random views and point lights for optimisation and evaluation (paper eq. 1).

A :class:`View` is a perspective camera looking at the origin from ``distance`` along a
direction given by azimuth (about +y, 0 = looking from +z) and elevation, and a point light
at ``light_distance`` in a direction within ``light_cone`` degrees of the camera's. Training
and test views come from independent seeds, so test views are never optimised against.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pandas as pd

from neurender.rng import stable_seed


@dataclasses.dataclass(frozen=True)
class View:
    """Camera ``origin`` looking at ``target`` (y up), vertical-and-horizontal ``fov`` in
    degrees (square images), and the point light's ``light`` position; world space."""

    origin: tuple[float, float, float]
    target: tuple[float, float, float]
    light: tuple[float, float, float]
    fov: float
    azimuth: float
    elevation: float


def direction(azimuth_deg: float, elevation_deg: float) -> np.ndarray:
    """Unit vector ``(3,)``: azimuth about +y from +z towards +x, elevation towards +y."""
    a, e = math.radians(azimuth_deg), math.radians(elevation_deg)
    return np.array([math.sin(a) * math.cos(e), math.sin(e), math.cos(a) * math.cos(e)])


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
    rng = np.random.default_rng(stable_seed(seed, "simplify", "views", split))
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
                tuple(map(float, eye * distance)),
                (0.0, 0.0, 0.0),
                tuple(map(float, light * light_distance)),
                fov,
                float(az),
                float(el),
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
            (float(r.origin_x), float(r.origin_y), float(r.origin_z)),
            (0.0, 0.0, 0.0),
            (float(r.light_x), float(r.light_y), float(r.light_z)),
            float(r.fov),
            float(r.azimuth),
            float(r.elevation),
        )
        for r in frame.itertuples()
    ]


def camera_basis(view: View) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mitsuba's ``look_at`` frame: ``(left, up, forward)`` unit vectors ``(3,)`` each."""
    forward = np.subtract(view.target, view.origin)
    forward = forward / np.linalg.norm(forward)
    left = np.cross([0.0, 1.0, 0.0], forward)
    left /= np.linalg.norm(left)
    return left, np.cross(forward, left), forward


def pixel_rays(view: View, width: int) -> np.ndarray:
    """Unit ray directions ``(W, W, 3)`` through pixel centres, row 0 at the top, matching
    Mitsuba's ``perspective`` sensor (image left = camera +x = ``left``)."""
    left, up, forward = camera_basis(view)
    tan = math.tan(math.radians(view.fov) / 2)
    c = 1 - (np.arange(width) + 0.5) / width * 2  # +1 at the left / top edge
    y, x = np.meshgrid(c, c, indexing="ij")
    d = forward + tan * (x[..., None] * left + y[..., None] * up)
    return d / np.linalg.norm(d, axis=-1, keepdims=True)
