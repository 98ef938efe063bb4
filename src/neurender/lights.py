"""Procedural HDR light probes as lat-long maps (linear RGB, y up; see :mod:`neurender.sh`).

Built-ins have real dynamic range: a small bright emitter (sun or window) several hundred
times brighter than the sky around it, plus coloured fill, so that occlusion matters.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterable
from dataclasses import dataclass
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


#: A map one texel of which holds more than this share of its energy is a point light in
#: the dark: a real outdoor map keeps a tenth or more in its sky and ground, and its sun
#: spans a few texels of a full-size map (:func:`probe_energy`).
SINGLE_TEXEL_SHARE = 0.99
#: Radiance below this displays as 0 of 255 after Reinhard and gamma 2.2
#: (:func:`neurender.display.tonemap`), as the figures and the tone-mapped scores see it.
_HALF_STEP = (0.5 / 255) ** 2.2
DISPLAY_BLACK = _HALF_STEP / (1 - _HALF_STEP)


@dataclass(frozen=True)
class ProbeEnergy:
    """A lat-long map's energy: radiance x texel solid angle (midpoint rule,
    :func:`neurender.sh.latlong_directions`), summed over texels and R, G, B (radiance
    units x steradians). ``positive`` is also the energy of the map once its negative values
    are clamped to 0."""

    #: Energy of the positive values.
    positive: float
    #: Energy of the negative values, as a magnitude (>= 0).
    negative: float
    #: How many values (texels x channels) are negative, and how many there are.
    negative_values: int
    values: int
    #: The brightest texel (R + G + B energy) as ``(row, column)`` and its share of
    #: ``positive`` (0 for a map without positive energy).
    peak_texel: tuple[int, int]
    peak_share: float
    #: The largest value of any channel: no render under the map (energy-conserving
    #: BRDFs) is brighter.
    peak_radiance: float

    @property
    def negative_share(self) -> float:
        """``negative / positive``; infinite for negative values without positive energy."""
        if self.positive > 0:
            return self.negative / self.positive
        return math.inf if self.negative > 0 else 0.0


def probe_energy(image: np.ndarray) -> ProbeEnergy:
    """The :class:`ProbeEnergy` of ``image`` ``(H, 2H, 3)`` linear radiance (finite)."""
    height, width = image.shape[:2]
    # The midpoint solid angle of a texel of each row, as neurender.sh.latlong_directions
    # (without its (H, W, 3) directions: downloaded maps are 8k wide).
    theta = math.pi * (np.arange(height) + 0.5) / height
    rows = (2 * math.pi / width) * (math.pi / height) * np.sin(theta)
    texels = np.maximum(image, 0).sum(-1, dtype=np.float64) * rows[:, None]
    negative = np.minimum(image, 0).sum((1, 2), dtype=np.float64) @ rows
    peak = np.unravel_index(int(texels.argmax()), texels.shape)
    total = float(texels.sum())
    return ProbeEnergy(
        positive=total,
        negative=-float(negative),
        negative_values=int(np.count_nonzero(image < 0)),
        values=int(image.size),
        peak_texel=(int(peak[0]), int(peak[1])),
        peak_share=float(texels[peak] / total) if total > 0 else 0.0,
        peak_radiance=float(image.max()),
    )


def clamp_negative(image: np.ndarray, label: str) -> np.ndarray:
    """``image`` ``(H, 2H, 3)`` (finite) with negative values set to 0, checked by its
    energy (:func:`probe_energy`); ``label`` names the map in messages (``light probe
    <file> (<config key>)``).

    Resampled or compressed HDR maps (cubic filters, lossy EXR) ring next to the sun; the
    negative lobes are small against the sun's energy and mean nothing physically, so
    they are clamped with a warning stating their share of the map's positive energy.

    Raises:
        ValueError: for a map without positive radiance (all zeros, or nothing left once
            the negatives are clamped), or whose negative values hold at least as much
            energy as its positive ones (signed data such as a difference or log image,
            not ringing).

    Also warns (without refusing) when no render under the map can show above black
    (:data:`DISPLAY_BLACK`) and when one texel holds nearly all its energy
    (:data:`SINGLE_TEXEL_SHARE`).
    """
    e = probe_energy(image)
    if e.positive <= 0:
        found = (
            f"{e.negative_values} of {e.values} values are negative and the rest 0, so "
            "nothing is left once negative values are clamped to 0"
            if e.negative_values
            else f"all {e.values} values are 0"
        )
        raise ValueError(
            f"{label} has no positive radiance ({found}); expected a map with positive radiance"
        )
    if e.negative >= e.positive:
        raise ValueError(
            f"{label}: its {e.negative_values} negative values (of {e.values}) hold "
            f"{100 * e.negative_share:.3g}% of its positive energy (solid-angle weighted), "
            "more than ringing next to a sun: signed data, not radiance; expected a map "
            "with positive radiance"
        )
    if e.negative_values:
        log.warning(
            "%s: clamped %d negative values (of %d) to 0; their energy was %.3g%% of the "
            "map's positive energy (solid-angle weighted, R + G + B)",
            label,
            e.negative_values,
            e.values,
            100 * e.negative_share,
        )
    if e.peak_radiance < DISPLAY_BLACK:
        log.warning(
            "%s: its brightest value is %.3g, below %.2g, the least radiance a figure or a "
            "tone-mapped score tells from black (Reinhard, gamma 2.2, 8 bits): every render "
            "under it is black; expected radiance on the built-in maps' scale (sky about 1)",
            label,
            e.peak_radiance,
            DISPLAY_BLACK,
        )
    if e.peak_share > SINGLE_TEXEL_SHARE:
        log.warning(
            "%s: one texel (row %d, column %d) holds %.4g%% of its energy: a point light in "
            "a black sky, every shadow black (a real outdoor map keeps a tenth or more in "
            "its sky and ground); check the map's exposure and look for a hot pixel",
            label,
            *e.peak_texel,
            100 * e.peak_share,
        )
    return np.maximum(image, 0) if e.negative_values else image


def _layer_name(layer: str) -> str:
    """A layer as messages name it: ``'sky'``, or ``unprefixed`` for ``R``, ``G``, ``B``."""
    return repr(layer) if layer else "unprefixed"


def rgb_layer(channels: Iterable[str], label: str) -> tuple[str, str, str]:
    """The channel names ``(R, G, B)`` of the one layer a light probe's radiance is read
    from. A channel's layer is its name up to the last ``.`` (``sky.R``: ``sky``;
    ``ViewLayer.Env.R``: ``ViewLayer.Env``; ``R``: the unprefixed layer). The layer is the
    only one with all of R, G and B, or the unprefixed one when several have them (the
    OpenEXR convention for a multi-layer file's main image); channels of different layers
    are never mixed. ``label`` names the file in messages.

    Raises:
        ValueError: when no layer has all three (each layer with some of them named with
            those it lacks), or several prefixed layers have them and no unprefixed one does.
    """
    layers: dict[str, set[str]] = {}
    for name in channels:
        layer, _, channel = name.rpartition(".")
        if channel in ("R", "G", "B"):
            layers.setdefault(layer, set()).add(channel)
    complete = sorted(layer for layer, found in layers.items() if len(found) == 3)
    if not complete:
        lacking = "".join(
            f"; layer {_layer_name(layer)} lacks {', '.join(c for c in 'RGB' if c not in found)}"
            for layer, found in sorted(layers.items())
        )
        raise ValueError(
            f"{label} needs R, G and B channels of one layer; it has {sorted(channels)}"
            f"{lacking} (channels of different layers are never mixed)"
        )
    if len(complete) > 1 and "" not in complete:
        raise ValueError(
            f"{label} has {len(complete)} layers with R, G and B channels: "
            f"{', '.join(map(_layer_name, complete))}; expected one RGB layer, or unprefixed "
            "R, G, B (used when present): re-export the map with its environment layer "
            "only, or name that layer's channels R, G, B"
        )
    layer = "" if "" in complete else complete[0]
    prefix = f"{layer}." if layer else ""
    return f"{prefix}R", f"{prefix}G", f"{prefix}B"


def load_probe(path: str | Path, key: str = "") -> np.ndarray:
    """A user lat-long EXR with channels R, G, B of one layer (:func:`rgb_layer`) as
    ``(H, W, 3)`` float32, ``W = 2H``, its negative values clamped to 0
    (:func:`clamp_negative`: a warning states their share of the map's energy). ``key``
    is the config key that names the file (``prt.user_probes.<name>``), given in every
    message after the file.

    Raises:
        ValueError: naming the file (and ``key``), for missing channels or several RGB
            layers (:func:`rgb_layer`), a map that is not 2:1, NaN or infinite radiance, or
            no positive radiance (:func:`clamp_negative`).
    """
    label = f"light probe {path}" + (f" ({key})" if key else "")
    chans = io.read_exr(path)
    names = rgb_layer(chans, label)
    img = np.stack([chans[k].astype(np.float32) for k in names], -1)
    if img.shape[1] != 2 * img.shape[0]:
        raise ValueError(
            f"{label} is {img.shape[1]}x{img.shape[0]}; a lat-long map is 2:1 (W = 2H)"
        )
    bad = ~np.isfinite(img)
    if bad.any():
        raise ValueError(
            f"{label} has {int(bad.sum())} NaN or infinite values (first at row, "
            f"column {tuple(int(i) for i in np.argwhere(bad)[0][:2])}); re-export the map"
        )
    return clamp_negative(img, label)


def write_probe(path: str | Path, image: np.ndarray) -> None:
    """Write an ``(H, W, 3)`` probe as an RGB EXR."""
    io.write_exr(path, {c: image[..., k] for k, c in enumerate("RGB")})
