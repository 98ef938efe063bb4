"""Coarse shading ``S_D`` and ``S_S`` as real-time renderers compute it: a few table
lookups per pixel, in torch (vectorised, exportable to ONNX with the network).

The quantities are those of :mod:`neurender.ndr.shading` (its importance-sampled estimator
is the reference these are tested against): ``S_D = integral L(w) max(n.w, 0) / pi dw``
and the GGX shading with Fresnel = 1, ``S_S = integral L(l) D(h) G(v, l) / (4 n.v) dl``.

* ``S_D`` of the map less its lights (below) from its 5-band SH (the light the NDR stage
  already has, :func:`neurender.ndr.environments.sh_features`, less the lights' own SH):
  the irradiance is the SH convolved with the clamped cosine (Ramamoorthi and Hanrahan
  2001), a dot product per pixel, clamped at 0.
* Bright texels as lights (our change): a small sun holds most of a real map's power in
  one texel of the coarse map, which the prefiltered copies smear over 10-20 degrees and
  the SH ring around (without lights ``S_S`` was 20-25 % off under the real-world-like
  maps; with them 1-2 % off the shading of the full map, closer than the importance
  estimator's 64 samples on every benchmark map:
  ``benchmarks/results/coarse_shading_accuracy.csv``). The texels that the importance
  estimator samples explicitly (:func:`neurender.ndr.shading.bright_texels`) become small
  disk lights instead (:func:`bright_lights`): direction and angular radius from the
  full map's power inside the texel, shaded analytically (``S_D``: ``max(n.l, 0) / pi``;
  ``S_S``: GGX with the lobe widened by the disk, ``alpha'^2 = alpha^2 + radius^2 / 8``,
  the disk's slope variance added to the lobe's, as Karis 2013's sphere lights widen
  theirs), and are removed from what the SH and the prefiltered copies shade.
* ``S_S`` of the rest by the split sum (Karis 2013): ``S_S ~ L_pre(r, roughness) E(n.v, roughness)``
  with ``r`` the mirror direction leant towards the normal as the surface roughens
  (Lagarde and de Rousiers 2014). ``L_pre`` is the map convolved with the GGX lobe under
  Karis' assumption ``n = v = r`` (weight ``D(h) max(r.l, 0)``) at :data:`LEVELS`
  roughnesses ``0, 1 / (LEVELS - 1), ..., 1`` (perceptual roughness, ``alpha =
  roughness^2``), read bilinearly in the map and linearly between levels
  (:func:`prefilter`: one fixed matrix per map size, so prefiltering a map is one product).
  ``E`` is the GGX directional albedo; with Fresnel 1 it is the sum of Karis' scale and
  bias of ``F0`` (``F0 = 1``), one table over ``(n.v, roughness)`` computed once by
  importance sampling (:func:`albedo_table`).

Maps follow :mod:`neurender.sh` (lat-long ``(h, 2h, 3)``, y up, texel centres, linear
radiance); directions are world = view space (:mod:`neurender.ndr.render`). Per-pixel
inputs and outputs of :func:`diffuse_shading` and :func:`specular_shading` are channels
first, ``(B, 3, P)`` (as the G-buffers are stored), and inside them a per-pixel vector is
its three ``(B, P)`` components: in the shipped graph, ONNX Runtime broadcasts a pixel's
scalar over a last axis of 3 several times slower than it combines whole images (the
shading took 3.4 ms a frame pixel-major, 1.5 ms so; ``benchmarks/results/ndr_graph.csv``).
Clamps take float bounds: torch 2.x's ONNX exporter writes a float tensor's ``clamp(0,
1)`` with int bounds as a ``Clip`` whose bound inputs exist nowhere in the graph (ONNX
Runtime refuses the file).
"""

from __future__ import annotations

import functools
import math

import numpy as np
import torch

from neurender import sh
from neurender.geometry import dot_components
from neurender.ndr.environments import SH_BANDS
from neurender.ndr.shading import MAX_BRIGHT, bright_texels, ggx_d, smith_g1

#: Prefiltered maps per lighting, at perceptual roughness ``k / (LEVELS - 1)``.
LEVELS = 6
#: Entries per axis of the albedo table, and importance samples per entry (a square).
TABLE_SIZE, TABLE_SAMPLES = 32, 4096
#: Sub-directions per source texel (a side x side grid) in the prefilter's quadrature, so
#: a lobe narrower than a texel still sees the texel's whole solid angle.
SUPERSAMPLE = 4
#: Output texels weighted at once by :func:`prefilter_matrix` (its memory, not its result).
ROW_CHUNK = 256
#: ``n.v`` of the table's first column (the albedo of a grazing view is 0 for rough GGX).
MIN_COS = 1e-3
#: Light slots of :func:`bright_lights` (unused slots carry no power): as many texels as
#: the importance-sampled estimator samples explicitly. (8 would be as accurate on the
#: benchmark maps, which have 1 to 9 bright texels, and the shipped graph's shading twice
#: as fast; trained with 8 and a smaller U-Net, NDR was worse under the real-world-like
#: maps and still below 30x: benchmarks/results/ndr_coarse_shading_runs.csv.)
LIGHTS = MAX_BRIGHT
#: A light's row: unit direction (3), power per RGB channel (radiance x solid angle, 3),
#: angular radius in radians (1).
LIGHT_COLUMNS = 7


def _irradiance_scale(bands: int) -> torch.Tensor:
    """``(bands^2,)`` factors taking a map's SH to those of ``S_D`` (irradiance / pi):
    ``sqrt(4 pi / (2 l + 1)) z_l / pi`` with ``z_l`` the clamped cosine's zonal SH."""
    per_band = [
        math.sqrt(4 * math.pi / (2 * l + 1)) * sh.CLAMPED_COSINE_ZONAL[l] / math.pi
        for l in range(bands)  # noqa: E741 - l is the band
    ]
    return torch.tensor([s for l, s in enumerate(per_band) for _ in range(2 * l + 1)])  # noqa: E741


def bright_lights(
    environment: np.ndarray, coarse: np.ndarray, slots: int = LIGHTS
) -> tuple[torch.Tensor, torch.Tensor]:
    """The bright texels of ``coarse`` ``(h, 2h, 3)`` (the downsampled ``environment``
    ``(H, 2H, 3)``) as disk lights ``(slots, LIGHT_COLUMNS)`` float64, and ``coarse``
    without them ``(h, 2h, 3)`` float64 (their texels 0).

    The texels are those :func:`neurender.ndr.shading.bright_texels` samples explicitly.
    Each light gathers the full map's texels whose centres fall in its coarse texel: power
    their summed radiance x solid angle; direction their power-weighted mean direction,
    and radius ``sqrt(4 (1 - |mean|))`` (a disk of small radius ``r`` has mean resultant
    length ``1 - r^2 / 4``), each texel counted as a disk of its own solid angle, so a sun
    smaller than a coarse texel keeps its place and size. Unused slots: direction +y, no
    power, radius 0."""
    env = torch.from_numpy(np.asarray(environment, np.float64))
    small = torch.from_numpy(np.asarray(coarse, np.float64))
    h, w = small.shape[:2]
    lights = torch.zeros(slots, LIGHT_COLUMNS, dtype=torch.float64)
    lights[:, 1] = 1.0
    chosen = bright_texels(small, limit=slots)
    if chosen is None:
        return lights, small
    big_h, big_w = env.shape[:2]
    dirs, solid = (torch.from_numpy(a) for a in sh.latlong_directions(big_h, big_w))
    dirs, solid = dirs.reshape(-1, 3), solid.reshape(-1)
    power = env.reshape(-1, 3) * solid[:, None]
    # The coarse texel holding each full-map texel centre, and each texel's own extent.
    rows = ((2 * torch.arange(big_h) + 1) * h) // (2 * big_h)
    cols = ((2 * torch.arange(big_w) + 1) * w) // (2 * big_w)
    owner = (rows[:, None] * w + cols[None, :]).reshape(-1)
    resultant = 1 - solid / (4 * math.pi)
    weight = power.mean(-1)
    texels = h * w
    summed_power = torch.zeros(texels, 3, dtype=torch.float64).index_add_(0, owner, power)
    summed_dir = torch.zeros(texels, 3, dtype=torch.float64).index_add_(
        0, owner, dirs * (weight * resultant)[:, None]
    )
    k = chosen.rows * w + chosen.cols
    mean = summed_dir[k] / summed_power[k].mean(-1, keepdim=True)
    length = mean.norm(dim=-1)
    count = len(k)
    lights[:count, 0:3] = mean / length[:, None]
    lights[:count, 3:6] = summed_power[k]
    lights[:count, 6] = torch.sqrt((4 * (1 - length)).clamp(min=0))
    rest = small.clone().reshape(-1, 3)
    rest[k] = 0.0
    return lights, rest.reshape(h, w, 3)


def diffuse_shading(
    normals: torch.Tensor, coefficients: torch.Tensor, lights: torch.Tensor
) -> torch.Tensor:
    """``S_D`` ``(..., 3, P)`` at unit ``normals`` ``(..., 3, P)`` (channels first, see
    :func:`specular_shading`) from the map's SH ``coefficients`` ``(..., 25, 3)``
    (:func:`neurender.sh.project_latlong`, 5 bands) and its lights ``(..., K,
    LIGHT_COLUMNS)`` (:func:`bright_lights`): each light exactly, the rest of the map by the
    SH less the lights' own, clamped at 0."""
    bands = math.isqrt(coefficients.shape[-2])
    scale = _irradiance_scale(bands).to(coefficients.dtype)
    dirs, power = lights[..., 0:3], lights[..., 3:6]
    rest = coefficients - sh.eval_sh(dirs, bands).transpose(-1, -2) @ power
    basis = sh.eval_sh(normals, bands, axis=-2)  # (..., bands^2, P)
    direct = power.transpose(-1, -2) @ (dirs @ normals).clamp(min=0.0) / math.pi
    return ((rest * scale[:, None]).transpose(-1, -2) @ basis + direct).clamp(min=0.0)


def level_roughness(levels: int = LEVELS) -> np.ndarray:
    """The perceptual roughness ``(levels,)`` of each prefiltered map: 0 to 1, even steps."""
    return np.linspace(0.0, 1.0, levels)


@functools.lru_cache(maxsize=8)
def prefilter_matrix(height: int, levels: int = LEVELS) -> torch.Tensor:
    """``(levels, h 2h, h 2h)`` float64: row ``i`` of level ``k`` holds the weights of the
    source texels in output texel ``i`` (same ``(h, 2h)`` map, flattened row-major).

    Weight of a source direction ``l`` for the mirror direction ``r`` (output texel
    centre): ``D(r.h, alpha) max(r.l, 0) dw`` with ``h`` the half vector of ``r`` and ``l``
    (Karis 2013, ``n = v = r``), by midpoint quadrature over :data:`SUPERSAMPLE`^2
    sub-directions per texel, normalised per row. Level 0 (roughness 0) is the identity."""
    width = 2 * height
    out_dirs = torch.from_numpy(sh.latlong_directions(height, width)[0].reshape(-1, 3))
    side = SUPERSAMPLE
    sub = (torch.arange(side, dtype=torch.float64) + 0.5) / side
    theta = (torch.arange(height, dtype=torch.float64)[:, None] + sub) * math.pi / height
    phi = (torch.arange(width, dtype=torch.float64)[:, None] + sub) * 2 * math.pi / width
    t = theta[:, None, :, None].expand(height, width, side, side)
    p = phi[None, :, None, :].expand(height, width, side, side)
    src = torch.stack([t.sin() * p.sin(), t.cos(), -t.sin() * p.cos()], -1).reshape(-1, 3)
    d_omega = (t.sin() * (math.pi / height / side) * (2 * math.pi / width / side)).reshape(-1)
    texels = height * width
    matrices = [torch.eye(texels, dtype=torch.float64)]
    for roughness in level_roughness(levels)[1:]:
        alpha = torch.tensor(roughness**2, dtype=torch.float64)
        rows = []
        for chunk in torch.split(out_dirs, ROW_CHUNK):  # bounds the (chunk, T side^2) temporaries
            cos_rl = chunk @ src.T
            cos_rh = torch.sqrt(((1 + cos_rl) / 2).clamp(min=0))  # r.h, h = (r + l) / |r + l|
            w = ggx_d(cos_rh, alpha) * cos_rl.clamp(min=0) * d_omega
            rows.append(w.reshape(len(chunk), texels, side * side).sum(-1))
        w = torch.cat(rows)
        matrices.append(w / w.sum(1, keepdim=True))
    return torch.stack(matrices)


def prefilter(environment: torch.Tensor, levels: int = LEVELS) -> torch.Tensor:
    """The GGX-prefiltered maps ``(levels, h, 2h, 3)`` of a map ``(h, 2h, 3)`` (same dtype;
    :func:`prefilter_matrix`)."""
    h, w = environment.shape[:2]
    m = prefilter_matrix(h, levels).to(environment.dtype)
    return (m @ environment.reshape(h * w, 3)).reshape(levels, h, w, 3)


@functools.lru_cache(maxsize=2)
def albedo_table(size: int = TABLE_SIZE, samples: int = TABLE_SAMPLES) -> torch.Tensor:
    """GGX directional albedo with Fresnel 1, ``(size, size)`` float64: entry ``[i, j]``
    at ``n.v = max(i / (size - 1), MIN_COS)`` and perceptual roughness ``j / (size - 1)``
    (``alpha`` its square). Importance sampling of ``D(h) (n.h)`` on a midpoint grid of
    ``samples`` (a square; deterministic), weight ``G (v.h) / ((n.h) (n.v))``, the Smith
    ``G`` of :func:`neurender.ndr.shading.smith_g1` (Karis 2013's table at ``F0 = 1``)."""
    side = math.isqrt(samples)
    if side * side != samples:
        raise ValueError(f"albedo table samples={samples}: expected a square number")
    grid = (torch.arange(side, dtype=torch.float64) + 0.5) / side
    u0, u1 = (g.reshape(-1) for g in torch.meshgrid(grid, grid, indexing="ij"))
    cos_v = (torch.arange(size, dtype=torch.float64) / (size - 1)).clamp(min=MIN_COS)
    alpha = (torch.arange(size, dtype=torch.float64) / (size - 1)) ** 2
    cv, a = cos_v[:, None, None], alpha[None, :, None]
    v = torch.stack([torch.sqrt(1 - cv**2), torch.zeros_like(cv), cv], -1)  # (size, 1, 1, 3)
    tan2 = a**2 * u0 / (1 - u0)
    cos_h = 1 / torch.sqrt(1 + tan2)
    sin_h = torch.sqrt(1 - cos_h**2)
    phi = 2 * math.pi * u1
    h = torch.stack([sin_h * phi.cos(), sin_h * phi.sin(), cos_h.expand_as(sin_h)], -1)
    v_dot_h = (v * h).sum(-1)
    cos_l = 2 * v_dot_h * cos_h - cv  # n.l of l = 2 (v.h) h - v, n = +z
    valid = (cos_l > 0) & (v_dot_h > 0)
    g = smith_g1(cos_l, a) * smith_g1(cv.expand_as(cos_l), a)
    weight = torch.where(valid, g * v_dot_h / (cos_h * cv), 0.0)
    return weight.mean(-1)


def _table_lookup(table: torch.Tensor, cos_v: torch.Tensor, roughness: torch.Tensor):
    """Bilinear read of :func:`albedo_table` at ``cos_v`` and ``roughness`` (same shape)."""
    size = table.shape[0]
    x = cos_v.clamp(0.0, 1.0) * (size - 1)
    y = roughness.clamp(0.0, 1.0) * (size - 1)
    i0 = x.floor().clamp(max=size - 2)
    j0 = y.floor().clamp(max=size - 2)
    fx, fy = x - i0, y - j0
    i0, j0 = i0.long(), j0.long()
    flat = table.reshape(-1)
    base = i0 * size + j0
    return (
        flat[base] * (1 - fx) * (1 - fy)
        + flat[base + 1] * (1 - fx) * fy
        + flat[base + size] * fx * (1 - fy)
        + flat[base + size + 1] * fx * fy
    )


def _map_lookup(maps: torch.Tensor, dirs: torch.Tensor, roughness: torch.Tensor):
    """Trilinear read ``(B, 3, P)`` of prefiltered maps ``(B, L, h, 2h, 3)`` at unit
    ``dirs`` ``(B, 3, P)`` (channels first, see :func:`specular_shading`): bilinear between
    texel centres (wrapping in azimuth, clamped at the poles) and linear in ``roughness``
    ``(B, P)`` between the levels."""
    batch, levels, h, w, _ = maps.shape
    dx, dy, dz = dirs.unbind(1)
    theta = torch.arccos(dy.clamp(-1.0, 1.0))
    phi = torch.atan2(dx, -dz)
    y = theta / math.pi * h - 0.5
    x = phi / (2 * math.pi) * w - 0.5
    s = roughness.clamp(0.0, 1.0) * (levels - 1)
    r0, c0 = y.floor(), x.floor()
    k0 = s.floor().clamp(max=levels - 2)
    fy, fx, fk = y - r0, x - c0, s - k0
    rows = [r0.clamp(0, h - 1).long(), (r0 + 1).clamp(0, h - 1).long()]
    cols = [torch.remainder(c0, w).long(), torch.remainder(c0 + 1, w).long()]
    first = (torch.arange(batch, device=maps.device)[:, None] * levels + k0.long()) * h
    index, weight = [], []
    for dk, wk in ((0, 1 - fk), (1, fk)):
        for row, wr in zip(rows, (1 - fy, fy), strict=True):
            for col, wc in zip(cols, (1 - fx, fx), strict=True):
                index.append((first + dk * h + row) * w + col)
                weight.append(wk * wr * wc)
    # The eight corners in one gather of RGB rows, then channels first, so that each
    # corner's weight scales whole (B, P) images (see specular_shading).
    corners = maps.reshape(-1, 3)[torch.stack(index).reshape(-1)].T
    corners = corners.reshape(3, 8, batch, -1).unbind(1)  # 8 x (3, B, P)
    out = sum(c * wt for c, wt in zip(corners, weight, strict=True))
    return out.transpose(0, 1)


def light_specular(
    normals: torch.Tensor, view_dirs: torch.Tensor, alpha: torch.Tensor, lights: torch.Tensor
) -> torch.Tensor:
    """``S_S`` ``(B, 3, P)`` of the disk lights ``(B, K, LIGHT_COLUMNS)``
    (:func:`bright_lights`) alone: per light, its power x ``D(h) G(v, l) / (4 n.v)`` at its
    direction, ``D`` widened by its radius (module docstring); unit ``normals``,
    ``view_dirs`` ``(B, 3, P)`` (channels first), GGX width ``alpha`` ``(B, P)``."""
    dirs, power, radius = lights[..., 0:3], lights[..., 3:6], lights[..., 6:7]
    n_dot_l = dirs @ normals  # (B, K, P)
    v_dot_l = dirs @ view_dirs
    n_dot_v = dot_components(normals.unbind(1), view_dirs.unbind(1))[:, None]  # (B, 1, P)
    # n.h with h = (l + v) / |l + v| and |l + v|^2 = 2 + 2 v.l: no (B, K, 3, P) temporaries.
    cos_h = (n_dot_l + n_dot_v) / torch.sqrt((2 + 2 * v_dot_l).clamp(min=1e-12))
    a = alpha[:, None]
    widened = torch.sqrt(a * a + radius * radius / 8)
    brdf = ggx_d(cos_h, widened) * smith_g1(n_dot_l, a) * smith_g1(n_dot_v, a)
    brdf = torch.where((n_dot_l > 0) & (n_dot_v > 0), brdf / (4 * n_dot_v.clamp(min=1e-7)), 0.0)
    return power.transpose(1, 2) @ brdf


def specular_shading(
    normals: torch.Tensor,
    view_dirs: torch.Tensor,
    alpha: torch.Tensor,
    maps: torch.Tensor,
    table: torch.Tensor,
    lights: torch.Tensor,
) -> torch.Tensor:
    """``S_S`` ``(B, 3, P)``: the lights (:func:`light_specular`) and the rest of the map by
    the split sum (module docstring): unit ``normals`` and ``view_dirs`` ``(B, 3, P)``
    (towards the eye), GGX width ``alpha`` ``(B, P)``, the prefiltered maps of the map
    without its lights ``(B, L, h, 2h, 3)`` (:func:`prefilter`), :func:`albedo_table` and
    the lights ``(B, K, LIGHT_COLUMNS)``; 0 where ``n.v <= 0``.

    Channels first, and per-pixel vectors as their three ``(B, P)`` components: ONNX
    Runtime broadcasts a per-pixel scalar over a last axis of 3 (or reduces over it)
    several times slower than it combines whole ``(B, P)`` images, which made this the
    shipped graph's costliest part."""
    n, v = normals.unbind(1), view_dirs.unbind(1)
    cos_v = dot_components(n, v)
    # The lobe of a rough surface leans from the mirror direction towards the normal
    # (Lagarde and de Rousiers 2014, "dominant direction"): without this the maps are read
    # too near the horizon and S_S of roughness 0.9 comes out up to 2x too dark.
    smooth = 1 - alpha.clamp(0.0, 1.0)
    lean = smooth * (torch.sqrt(smooth) + alpha)
    mirror = [2 * cos_v * ni - vi for ni, vi in zip(n, v, strict=True)]
    dominant = [ni + lean * (mi - ni) for ni, mi in zip(n, mirror, strict=True)]
    length = torch.sqrt(dot_components(dominant, dominant)).clamp(min=1e-12)
    dominant = torch.stack([d / length for d in dominant], 1)
    roughness = torch.sqrt(alpha.clamp(0.0, 1.0))
    radiance = _map_lookup(maps, dominant, roughness)
    albedo = _table_lookup(table.to(normals.dtype), cos_v, roughness)
    rest = torch.where(cos_v > 0, albedo, 0.0)[:, None] * radiance
    return rest + light_specular(normals, view_dirs, alpha, lights)


def prefiltered_shading(
    normals: torch.Tensor,
    view_dirs: torch.Tensor,
    alpha: torch.Tensor,
    coefficients: torch.Tensor,
    maps: torch.Tensor,
    lights: torch.Tensor,
) -> tuple[torch.Tensor, torch.Tensor]:
    """``S_D`` and ``S_S`` ``(P, 3)`` for ``P`` points under one lighting
    (:func:`lighting`): the counterpart of :func:`neurender.ndr.shading.coarse_shading`.

    Args:
        normals, view_dirs: ``(P, 3)`` unit vectors (view_dir points to the eye).
        alpha: ``(P,)`` GGX width.
        coefficients: ``(25, 3)`` the map's 5-band SH.
        maps: ``(L, h, 2h, 3)`` the prefiltered maps of its coarse copy without its lights.
        lights: ``(K, LIGHT_COLUMNS)`` its bright texels as lights (:func:`bright_lights`).
    """
    dtype = normals.dtype
    lights = lights.to(dtype)
    s_d = diffuse_shading(normals.T, coefficients.to(dtype), lights).T
    s_s = specular_shading(
        normals.T[None],
        view_dirs.T[None],
        alpha[None].to(dtype),
        maps[None].to(dtype),
        albedo_table(),
        lights[None],
    )[0].T
    return s_d, s_s


def lighting(
    environment: np.ndarray, coarse: np.ndarray
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """The fast shading's lighting of one map, float64: the 5-band SH ``(25, 3)`` of
    ``environment`` ``(H, 2H, 3)`` (what the network's light input is made of), the
    prefiltered maps ``(L, h, 2h, 3)`` of its downsampled copy ``coarse`` ``(h, 2h, 3)``
    without its bright texels, and those texels as lights ``(LIGHTS, LIGHT_COLUMNS)``
    (:func:`bright_lights`)."""
    coefficients = torch.from_numpy(sh.project_latlong(environment, SH_BANDS))
    lights, rest = bright_lights(environment, coarse)
    return coefficients, prefilter(rest), lights
