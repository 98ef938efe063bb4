"""Procedural HDR light probes as lat-long maps (linear RGB, y up; see :mod:`neurender.sh`).

Built-ins have real dynamic range: a small bright emitter (sun or window) several hundred
times brighter than the sky around it, plus coloured fill, so that occlusion matters.
"""

from __future__ import annotations

import logging
import math
from pathlib import Path

import numpy as np

from neurender import io, sh

log = logging.getLogger(__name__)

BUILTIN_PROBES = ("sky", "sunset", "studio")


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


def _disk(dirs: np.ndarray, centre, angular_radius_deg: float) -> np.ndarray:
    """Soft-edged indicator ``(H, W)`` of directions within the given angle of ``centre``."""
    cos_r = math.cos(math.radians(angular_radius_deg))
    c = dirs @ _unit(centre)
    return np.clip((c - cos_r) / (1.0 - cos_r) * 4.0, 0.0, 1.0)


def procedural_probe(name: str, height: int) -> np.ndarray:
    """A built-in probe ``(height, 2 height, 3)`` float32 linear radiance."""
    dirs, _ = sh.latlong_directions(height, 2 * height)
    up = dirs[..., 1:2]
    if name == "sky":
        sky = np.where(
            up > 0, (1 - up) * np.array([0.9, 0.95, 1.0]) + up * np.array([0.25, 0.45, 0.95]), 0.0
        )
        ground = np.where(up <= 0, np.array([0.18, 0.14, 0.1]), 0.0)
        sun = _disk(dirs, [0.5, 0.75, 0.45], 4.0)[..., None] * np.array([60.0, 55.0, 48.0])
        img = sky + ground + sun
    elif name == "sunset":
        glow = np.exp(-np.abs(up) * 6.0) * np.array([1.2, 0.55, 0.25])
        sky = np.where(up > 0, up * np.array([0.3, 0.25, 0.6]), np.array([0.05, 0.04, 0.05]))
        sun = _disk(dirs, [-0.8, 0.15, -0.3], 5.0)[..., None] * np.array([50.0, 24.0, 8.0])
        img = glow + sky + sun
    elif name == "studio":
        key = _disk(dirs, [0.6, 0.5, 0.6], 12.0)[..., None] * np.array([12.0, 12.0, 11.0])
        rim = _disk(dirs, [-0.7, 0.3, -0.6], 8.0)[..., None] * np.array([4.0, 6.0, 10.0])
        fill = 0.15 * (0.6 + 0.4 * up) * np.array([1.0, 0.85, 0.7])
        img = key + rim + fill
    else:
        raise KeyError(f"unknown built-in probe {name!r}; expected one of {BUILTIN_PROBES}")
    return img.astype(np.float32)


def clamp_negative(image: np.ndarray) -> tuple[np.ndarray, int, float]:
    """``image`` ``(H, 2H, 3)`` with negative values set to 0, how many there were and the
    energy that adds relative to the clamped map's total (both weighted by solid angle,
    summed over channels; 0 for a map without energy).

    Resampled or compressed HDR maps (cubic filters, lossy EXR) ring next to the sun; the
    negative lobes are small against the sun's energy and mean nothing physically.
    """
    negative = image < 0
    count = int(negative.sum())
    if not count:
        return image, 0, 0.0
    _, solid_angle = sh.latlong_directions(*image.shape[:2])
    clamped = np.where(negative, 0, image).astype(image.dtype)
    weight = solid_angle[..., None]
    added = float(-(np.where(negative, image, 0) * weight).sum())
    total = float((clamped * weight).sum())
    return clamped, count, added / total if total > 0 else 0.0


def load_probe(path: str | Path) -> np.ndarray:
    """A user lat-long EXR with channels R, G, B as ``(H, W, 3)`` float32, ``W = 2H``.

    Negative values (ringing of resampled maps) are clamped to 0 with a logged warning
    that states their count and the energy the clamp adds (:func:`clamp_negative`).

    Raises:
        ValueError: naming the file, for missing channels, a map that is not 2:1, or NaN
            or infinite radiance.
    """
    chans = io.read_exr(path)
    names = [next((k for k in chans if k.split(".")[-1] == c), None) for c in "RGB"]
    if None in names:
        raise ValueError(f"light probe {path} needs R, G and B channels; it has {sorted(chans)}")
    img = np.stack([chans[k].astype(np.float32) for k in names], -1)
    if img.shape[1] != 2 * img.shape[0]:
        raise ValueError(
            f"light probe {path} is {img.shape[1]}x{img.shape[0]}; a lat-long map is 2:1 (W = 2H)"
        )
    bad = ~np.isfinite(img)
    if bad.any():
        raise ValueError(
            f"light probe {path} has {int(bad.sum())} NaN or infinite values (first at row, "
            f"column {tuple(int(i) for i in np.argwhere(bad)[0][:2])}); re-export the map"
        )
    img, count, added = clamp_negative(img)
    if count:
        log.warning(
            "light probe %s: clamped %d negative values (of %d) to 0, adding %.3g%% of the "
            "map's energy",
            path,
            count,
            img.size,
            100 * added,
        )
    return img


def write_probe(path: str | Path, image: np.ndarray) -> None:
    """Write an ``(H, W, 3)`` probe as an RGB EXR."""
    io.write_exr(path, {c: image[..., k] for k, c in enumerate("RGB")})
