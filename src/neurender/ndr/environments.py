"""HDR environment maps for NDR: random procedural ones, user EXR folders, SH and downsampling.

Maps are lat-long ``(H, 2H, 3)`` float32 linear radiance in the convention of
:mod:`neurender.sh` (y up, ``u = atan2(x, -z) / 2 pi``, texel centres; Mitsuba gets them
through :func:`neurender.mitsuba_setup.envmap_rows`). The network's
light input is the 5-band SH projection, 25 coefficients x RGB = 75 numbers, ordered
coefficient-major (``k * 3 + channel``, ``k = l (l + 1) + m``).

Real outdoor maps put more than half of their power in the sun, one texel of a coarse
map; :func:`random_environment` draws a share of such maps and :func:`sunlit_environment`
only such maps (the real-world-like test set). User maps are loaded (and checked) once per
process by :func:`user_map`.
"""

from __future__ import annotations

import colorsys
import functools
import math
from pathlib import Path

import numpy as np
import torch

from neurender import lights, sh
from neurender.ndr import user_probe_files, user_probe_strays, user_probes_problem

SH_BANDS = 5
SH_FEATURES = SH_BANDS**2 * 3
#: The sun of outdoor maps: its angular diameter (degrees) and its radiance range as a
#: multiple of the sky level (log-uniform; the real sun is about 1e5 to 3e5 x a clear sky's
#: zenith, and our skies carry a fill lobe besides).
SMALL_SUN_DIAMETER_DEG = 0.53
SMALL_SUN_RADIANCE = (5e4, 1e6)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def _random_direction(rng: np.random.Generator, min_elevation_deg: float) -> np.ndarray:
    """Uniform azimuth; elevation uniform in sine above ``min_elevation_deg``."""
    s = rng.uniform(math.sin(math.radians(min_elevation_deg)), 1.0)
    phi = rng.uniform(0, 2 * math.pi)
    c = math.sqrt(1 - s * s)
    return np.array([c * math.sin(phi), s, -c * math.cos(phi)])


def _colour(rng: np.random.Generator, saturation: float) -> np.ndarray:
    return np.array(colorsys.hsv_to_rgb(rng.uniform(), rng.uniform(0, saturation), 1.0))


def texel_solid_angles(height: int) -> np.ndarray:
    """Exact solid angle ``(height,)`` of one texel per row of a ``(height, 2 height)``
    lat-long map, steradians (``(2 pi / W) (cos theta0 - cos theta1)``)."""
    edges = np.cos(np.pi * np.arange(height + 1) / height)
    return (edges[:-1] - edges[1:]) * (np.pi / height)


def add_small_sun(image: np.ndarray, direction: np.ndarray, radiance: np.ndarray) -> np.ndarray:
    """``image`` ``(H, 2H, 3)`` plus a sun of :data:`SMALL_SUN_DIAMETER_DEG` and ``radiance``
    (RGB) centred on unit ``direction``: its power (radiance x its solid angle) deposited
    in the one texel holding ``direction``, as an area-weighted downsampling of a finer map
    would (a half-degree disk is below a texel at any size used here)."""
    height, width = image.shape[:2]
    radius = math.radians(SMALL_SUN_DIAMETER_DEG / 2)
    power = np.asarray(radiance, np.float64) * 2 * math.pi * (1 - math.cos(radius))
    theta = math.acos(float(np.clip(direction[1], -1, 1)))
    phi = math.atan2(direction[0], -direction[2]) % (2 * math.pi)
    row = min(int(theta / math.pi * height), height - 1)
    col = min(int(phi / (2 * math.pi) * width), width - 1)
    out = image.copy()
    out[row, col] += (power / texel_solid_angles(height)[row]).astype(image.dtype)
    return out


def procedural_environment(
    rng: np.random.Generator, height: int, small_sun_fraction: float = 0.0
) -> tuple[np.ndarray, str]:
    """:func:`random_environment`'s map and its name: ``procedural sun`` for a map with
    the small outdoor sun, else ``procedural``."""
    return _random_environment(rng, height, small_sun_fraction)


def random_environment(
    rng: np.random.Generator, height: int, small_sun_fraction: float = 0.0
) -> np.ndarray:
    """A random map ``(height, 2 height, 3)`` with real dynamic range.

    Sky gradient (zenith, horizon and ground colours), a coloured fill lobe, then with
    probability ``small_sun_fraction`` an outdoor sun as real maps have one
    (:data:`SMALL_SUN_DIAMETER_DEG` across, :data:`SMALL_SUN_RADIANCE` times the sky
    level, log-uniform: the sun then holds 27 % to 87 % of the coarse map's power, median
    60 %, in one texel; :func:`add_small_sun`), else one or two broad emitters: a sun (2-6
    degree disk, 100-2000 x the sky) or a window-like soft rectangle (2 % to 21 %, median
    5 %; :func:`sun_share`). ``small_sun_fraction`` 0 draws exactly the maps drawn before
    the small sun existed.
    """
    return _random_environment(rng, height, small_sun_fraction)[0]


def _random_environment(
    rng: np.random.Generator, height: int, small_sun_fraction: float
) -> tuple[np.ndarray, str]:
    dirs, _ = sh.latlong_directions(height, 2 * height)
    up = dirs[..., 1:2]
    sky_level = rng.uniform(0.1, 0.8)
    zenith, horizon = _colour(rng, 0.6) * sky_level, _colour(rng, 0.3) * sky_level
    ground = _colour(rng, 0.5) * sky_level * rng.uniform(0.1, 0.6)
    t = np.clip(up, 0, 1) ** 0.5
    img = np.where(up > 0, (1 - t) * horizon + t * zenith, ground)
    fill_dir = _random_direction(rng, -30)
    fill = np.clip(dirs @ fill_dir, 0, 1)[..., None] ** rng.uniform(1, 4)
    img = img + fill * _colour(rng, 0.8) * rng.uniform(0.1, 1.0)
    if small_sun_fraction > 0 and rng.uniform() < small_sun_fraction:
        low, high = np.log(SMALL_SUN_RADIANCE)
        level = sky_level * math.exp(rng.uniform(low, high))
        direction = _random_direction(rng, 5)
        sun = _colour(rng, 0.3) * level
        return add_small_sun(img.astype(np.float32), direction, sun), "procedural sun"
    for _ in range(int(rng.integers(1, 3))):
        centre = _random_direction(rng, 5)
        cos_angle = dirs @ centre
        if rng.uniform() < 0.5:  # sun
            radius = math.radians(rng.uniform(2, 6))
            edge = np.clip((cos_angle - math.cos(radius)) / (1 - math.cos(radius)) * 4, 0, 1)
            img = img + edge[..., None] * _colour(rng, 0.3) * rng.uniform(10, 120)
        else:  # window: a soft-edged rectangle in the tangent plane of its centre
            side = _unit(np.cross(centre, [0.0, 1.0, 0.0]) + 1e-6)
            upward = np.cross(side, centre)
            x, y = dirs @ side, dirs @ upward
            half_w, half_h = np.tan(np.radians(rng.uniform(8, 25, size=2)))
            inside = (
                np.clip((half_w - np.abs(x)) * 20, 0, 1)
                * np.clip((half_h - np.abs(y)) * 20, 0, 1)
                * (cos_angle > 0)
            )
            img = img + inside[..., None] * _colour(rng, 0.2) * rng.uniform(3, 15)
    return np.asarray(img, np.float32), "procedural"


def sunlit_environment(rng: np.random.Generator, height: int) -> np.ndarray:
    """A real-world-like outdoor map: :func:`random_environment` always with the small sun."""
    return random_environment(rng, height, small_sun_fraction=1.0)


def sun_share(image: np.ndarray, height: int = 16) -> float:
    """The brightest texel's share of the map's power (mean over RGB) once the map is
    downsampled to ``height`` rows (:func:`resize_latlong`; the paper's coarse map is
    32 x 16): about 0.3 at most for broad emitters, over 0.5 for real outdoor maps."""
    small = resize_latlong(image, height).astype(np.float64).mean(-1)
    power = small * texel_solid_angles(height)[:, None]
    return float(power.max() / power.sum())


def rotate_about_up(image: np.ndarray, columns: int) -> np.ndarray:
    """Rotate a lat-long map about +y by a whole number of pixel columns (exact)."""
    return np.roll(image, columns, axis=1)


def resize_latlong(image: np.ndarray, height: int) -> np.ndarray:
    """Area-weighted resampling of ``(H, 2H, 3)`` to ``(height, 2 height, 3)``.

    Each output pixel averages input radiance weighted by solid angle (``sin theta``),
    so the map's irradiance is kept.
    """
    h_in = image.shape[0]
    weight = np.sin(math.pi * (np.arange(h_in) + 0.5) / h_in)[:, None, None]
    x = torch.from_numpy(np.ascontiguousarray((image * weight).transpose(2, 0, 1)))[None]
    w = torch.from_numpy(np.broadcast_to(weight, (h_in, 2 * h_in, 1)).transpose(2, 0, 1).copy())
    size = (height, 2 * height)
    num = torch.nn.functional.interpolate(x.double(), size=size, mode="area")
    den = torch.nn.functional.interpolate(w[None].double(), size=size, mode="area")
    return (num / den)[0].permute(1, 2, 0).numpy().astype(np.float32)


def sh_features(image: np.ndarray) -> np.ndarray:
    """The network's light input: 5-band SH of the map, ``(75,)`` float32 (see module doc)."""
    return sh.project_latlong(image, SH_BANDS).reshape(-1).astype(np.float32)


def user_probes(folder: str | Path) -> list[Path]:
    """The lat-long maps in ``folder`` (:func:`neurender.ndr.user_probe_files`: ``.exr``
    in any case, sorted), each checked by :func:`neurender.lights.load_probe` when used
    (:func:`check_user_probes` checks all).

    Raises:
        FileNotFoundError: for a path that is no folder, or a folder without maps.
        ValueError: for a folder that holds other files than maps and notes, such as
            ``.hdr`` maps (:func:`neurender.ndr.user_probes_problem`; the config check
            refuses them too, but not in a folder the workflow makes).
    """
    path = Path(folder)
    if not path.is_dir():
        raise FileNotFoundError(f"ndr.user_probes_dir {path} is not a folder of EXR maps")
    if user_probe_strays(path):
        raise ValueError(user_probes_problem(path))
    found = user_probe_files(path)
    if not found:
        raise FileNotFoundError(f"ndr.user_probes_dir {path} holds no *.exr lat-long maps")
    return found


@functools.lru_cache(maxsize=64)
def user_map(path: Path, height: int) -> np.ndarray:
    """A user map resized to ``height`` rows (:func:`neurender.lights.load_probe`: negative
    values clamped with one warning, NaN, infinities, wrong shapes and maps without
    positive radiance refused naming the file and ``ndr.user_probes_dir``). Cached, so a
    process (and the processes it forks) warns once per map; treat the result as
    read-only."""
    return resize_latlong(lights.load_probe(path, "ndr.user_probes_dir"), height)


def check_user_probes(folder: str | Path, height: int) -> list[Path]:
    """Load every map of ``folder`` before any sample is rendered, so a bad map stops the
    job at once, naming its file; the maps found."""
    found = user_probes(folder)
    for path in found:
        user_map(path, height)
    return found


def environment_for_sample(
    rng: np.random.Generator,
    height: int,
    probes: list[Path],
    user_fraction: float,
    small_sun_fraction: float = 0.0,
) -> tuple[np.ndarray, str]:
    """A map for one sample and its name: with probability ``user_fraction`` a user probe
    (resized and randomly rotated), else a procedural one (also randomly rotated; a share
    ``small_sun_fraction`` of them with the small outdoor sun, :func:`random_environment`)."""
    if probes and rng.uniform() < user_fraction:
        path = probes[int(rng.integers(len(probes)))]
        image, name = user_map(path, height), path.stem
    else:
        image, name = procedural_environment(rng, height, small_sun_fraction)
    return rotate_about_up(image, int(rng.integers(2 * height))), name
