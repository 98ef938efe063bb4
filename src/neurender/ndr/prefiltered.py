"""Coarse shading ``S_D`` and ``S_S`` as real-time renderers compute it: a few table
lookups per pixel, in torch (vectorised, exportable to ONNX with the network).

The quantities are those of :mod:`neurender.ndr.shading` (its importance-sampled estimator
is the reference these are tested against): ``S_D = integral L(w) max(n.w, 0) / pi dw``
and the GGX shading with Fresnel = 1, ``S_S = integral L(l) D(h) G(v, l) / (4 n.v) dl``.

* ``S_D`` of the map less its lights (below) from its 5-band SH (the light the NDR stage
  already has, :func:`neurender.ndr.environments.sh_features`, less the lights' own SH):
  the irradiance is the SH convolved with the clamped cosine (Ramamoorthi and Hanrahan
  2001), clamped at 0. The clamped cosine has no band 3, so on the unit sphere the
  irradiance of bands 0 to 4 is a polynomial in the normal's degree-1 and homogeneous
  degree-4 monomials (:data:`MONOMIALS`, 18): one product per pixel with the map's 18
  coefficients (:func:`irradiance_monomials`), exactly the SH sum, in a sixth of the
  graph's nodes.
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
A map has as many lights as bright texels (:func:`bright_lights`, at most :data:`LIGHTS`;
the lights axis of the shipped graph is dynamic): the lights' share of a frame grows with
their number, as a real-time renderer's does, and no frame pays for empty slots.
Clamps take float bounds: torch 2.x's ONNX exporter writes a float tensor's ``clamp(0,
1)`` with int bounds as a ``Clip`` whose bound inputs exist nowhere in the graph (ONNX
Runtime refuses the file).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from typing import NamedTuple

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
#: At most this many lights per map (:func:`bright_lights`): as many texels as the
#: importance-sampled estimator samples explicitly. (With at most 8, and a smaller U-Net,
#: NDR was worse under the real-world-like maps: benchmarks/results/ndr_coarse_shading_runs.csv.)
LIGHTS = MAX_BRIGHT
#: A light's row: unit direction (3), power per RGB channel (radiance x solid angle, 3),
#: angular radius in radians (1).
LIGHT_COLUMNS = 7
#: Exponents ``(a, b, c)`` of the monomials ``x^a y^b z^c`` of a unit normal that
#: :func:`diffuse_shading` sums: degree 1 (band 1), then the homogeneous degree 4 (on the
#: unit sphere these span bands 0, 2 and 4; the clamped cosine has no band 3).
MONOMIALS = ((1, 0, 0), (0, 1, 0), (0, 0, 1)) + tuple(
    (a, b, 4 - a - b) for a in range(4, -1, -1) for b in range(4 - a, -1, -1)
)
#: The quadratic monomials, as the pairs of components they multiply.
_QUADRATIC = {(2, 0, 0): (0, 0), (0, 2, 0): (1, 1), (0, 0, 2): (2, 2)}
_QUADRATIC |= {(1, 1, 0): (0, 1), (1, 0, 1): (0, 2), (0, 1, 1): (1, 2)}
#: Each quartic monomial of :data:`MONOMIALS` as a product of two quadratic ones.
_QUARTIC_PAIRS = tuple(
    next((p, q) for p in _QUADRATIC for q in _QUADRATIC if np.array_equal(np.add(p, q), e))
    for e in MONOMIALS[3:]
)


def _irradiance_scale(bands: int) -> torch.Tensor:
    """``(bands^2,)`` float64 factors taking a map's SH to those of ``S_D`` (irradiance / pi):
    ``sqrt(4 pi / (2 l + 1)) z_l / pi`` with ``z_l`` the clamped cosine's zonal SH."""
    per_band = [
        math.sqrt(4 * math.pi / (2 * l + 1)) * sh.CLAMPED_COSINE_ZONAL[l] / math.pi
        for l in range(bands)  # noqa: E741 - l is the band
    ]
    factors = [s for l, s in enumerate(per_band) for _ in range(2 * l + 1)]  # noqa: E741
    return torch.tensor(factors, dtype=torch.float64)


def bright_lights(
    environment: np.ndarray, coarse: np.ndarray, limit: int = LIGHTS
) -> tuple[torch.Tensor, torch.Tensor]:
    """The bright texels of ``coarse`` ``(h, 2h, 3)`` (the downsampled ``environment``
    ``(H, 2H, 3)``) as ``K`` disk lights ``(K, LIGHT_COLUMNS)`` float64 (``K`` the
    texels', at most ``limit``; one without power where there are none), and ``coarse``
    without them ``(h, 2h, 3)`` float64 (their texels 0).

    The texels are those :func:`neurender.ndr.shading.bright_texels` samples explicitly.
    Each light gathers the full map's texels whose centres fall in its coarse texel: power
    their summed radiance x solid angle; direction their power-weighted mean direction,
    and radius ``sqrt(4 (1 - |mean|))`` (a disk of small radius ``r`` has mean resultant
    length ``1 - r^2 / 4``), each texel counted as a disk of its own solid angle, so a sun
    smaller than a coarse texel keeps its place and size."""
    env = torch.from_numpy(np.asarray(environment, np.float64))
    small = torch.from_numpy(np.asarray(coarse, np.float64))
    h, w = small.shape[:2]
    chosen = bright_texels(small, limit=limit)
    if chosen is None:
        return no_lights(1), small
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
    radius = torch.sqrt((4 * (1 - length)).clamp(min=0))
    lights = torch.cat([mean / length[:, None], summed_power[k], radius[:, None]], 1)
    rest = small.clone().reshape(-1, 3)
    rest[k] = 0.0
    return lights, rest.reshape(h, w, 3)


def no_lights(count: int, dtype: torch.dtype = torch.float64) -> torch.Tensor:
    """``count`` lights ``(count, LIGHT_COLUMNS)`` that shade nothing: direction +y, no
    power, radius 0 (what pads a batch of maps with fewer lights)."""
    lights = torch.zeros(count, LIGHT_COLUMNS, dtype=dtype)
    lights[:, 1] = 1.0
    return lights


def stack_lights(lights: Sequence[torch.Tensor]) -> torch.Tensor:
    """Maps' lights ``(K_i, LIGHT_COLUMNS)`` as one batch ``(B, max K_i, LIGHT_COLUMNS)``,
    each padded with :func:`no_lights` (which add exactly 0 to either shading)."""
    count = max(len(x) for x in lights)
    return torch.stack([torch.cat([x, no_lights(count - len(x), x.dtype)]) for x in lights])


def monomials(x: torch.Tensor, y: torch.Tensor, z: torch.Tensor) -> list[torch.Tensor]:
    """The :data:`MONOMIALS` of a unit vector's components (one shape each): 21 products."""
    components = (x, y, z)
    quadratic = {e: components[i] * components[j] for e, (i, j) in _QUADRATIC.items()}
    return [x, y, z, *(quadratic[p] * quadratic[q] for p, q in _QUARTIC_PAIRS)]


@functools.lru_cache(maxsize=4)
def irradiance_monomials(bands: int) -> tuple[torch.Tensor, torch.Tensor]:
    """The diffuse shading's SH in :data:`MONOMIALS`, float64: ``to_monomials``
    ``(18, bands^2)`` takes a map's SH ``c`` to the coefficients ``p = to_monomials @ c``
    of its ``S_D`` (``S_D(n) = sum_j p_j m_j(n)`` for unit ``n``, ``m`` the monomials), and
    ``kernel`` ``(18, 18)`` takes a light's monomials ``m(d)`` to those of the SH part of
    its ``S_D`` (``kernel @ m(d)``, for unit power), both exact on the unit sphere
    (bands up to 5: the monomials span the clamped cosine's bands 0 to 4).

    Fitted by least squares at 1024 directions and checked there to 1e-10."""
    check = np.random.default_rng(0).normal(size=(1024, 3))
    dirs = torch.from_numpy(check / np.linalg.norm(check, axis=1, keepdims=True))
    basis = sh.eval_sh(dirs, bands)  # (N, bands^2)
    m = torch.stack(monomials(*dirs.unbind(-1)), -1)  # (N, 18)
    scale = _irradiance_scale(bands)
    used = scale != 0  # band 3 (zero) is no polynomial of these monomials
    fit = torch.linalg.lstsq(m, basis[:, used]).solution  # (18, used): m @ fit = basis
    if float((m @ fit - basis[:, used]).abs().max()) > 1e-10:
        raise ValueError(f"irradiance_monomials({bands}): the SH are no polynomial of MONOMIALS")
    to_monomials = torch.zeros(len(MONOMIALS), bands * bands, dtype=torch.float64)
    to_monomials[:, used] = fit * scale[used]
    return to_monomials, to_monomials[:, used] @ fit.T


def diffuse_polynomial(coefficients: torch.Tensor, lights: torch.Tensor) -> torch.Tensor:
    """The coefficients ``(..., 18, 3)`` of :data:`MONOMIALS` whose sum is ``S_D`` of a map
    less its lights (per map, :func:`lighting`): from the map's SH ``coefficients``
    ``(..., 25, 3)`` (:func:`neurender.sh.project_latlong`, 5 bands) less the SH of its
    lights ``(..., K, LIGHT_COLUMNS)`` (:func:`bright_lights`), convolved with the clamped
    cosine (:func:`irradiance_monomials`)."""
    bands = math.isqrt(coefficients.shape[-2])
    to_monomials, kernel = (m.to(coefficients.dtype) for m in irradiance_monomials(bands))
    dirs, power = lights[..., 0:3], lights[..., 3:6]
    light_monomials = torch.stack(monomials(*dirs.unbind(-1)), -2)  # (..., 18, K)
    return to_monomials @ coefficients - kernel @ (light_monomials @ power)


def diffuse_shading(
    normals: torch.Tensor, irradiance: torch.Tensor, lights: torch.Tensor
) -> torch.Tensor:
    """``S_D`` ``(..., 3, P)`` at unit ``normals`` ``(..., 3, P)`` (channels first, see
    :func:`specular_shading`): the map less its lights by its :func:`diffuse_polynomial`
    ``irradiance`` ``(..., 18, 3)``, each light ``(..., K, LIGHT_COLUMNS)`` exactly,
    clamped at 0."""
    dirs, power = lights[..., 0:3], lights[..., 3:6]
    basis = torch.stack(monomials(*normals.unbind(-2)), -2)  # (..., 18, P)
    direct = power.transpose(-1, -2) @ (dirs @ normals).clamp(min=0.0) / math.pi
    return (irradiance.transpose(-1, -2) @ basis + direct).clamp(min=0.0)


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


def corner_cells(maps: torch.Tensor) -> torch.Tensor:
    """The prefiltered maps ``(L, h, 2h, 3)`` of one lighting (:func:`prefilter`) as the
    lookup reads them, ``(3, L - 1, h + 1, 2h + 1, 8)`` (per map, :func:`lighting`): padded
    (a column of the far side at each azimuth end, the pole rows repeated), then each cell's
    eight corners (two levels, two rows, two columns; level, row, column major) stored
    together per channel, so that a pixel's read is one index (:func:`_map_lookup`)."""
    levels, h, w, _ = maps.shape
    padded = torch.cat([maps[..., -1:, :], maps, maps[..., :1, :]], 2)
    padded = torch.cat([padded[:, :1], padded, padded[:, -1:]], 1)  # (L, h + 2, w + 2, 3)
    corners = [
        padded[dk : levels - 1 + dk, dr : h + 1 + dr, dc : w + 1 + dc]
        for dk in (0, 1)
        for dr in (0, 1)
        for dc in (0, 1)
    ]
    return torch.stack(corners, -1).permute(3, 0, 1, 2, 4).contiguous()


def _interpolate(cells: torch.Tensor, index: torch.Tensor, fractions) -> torch.Tensor:
    """``(C, B, P)`` multilinear reads of ``cells`` ``(C, N, 2^d)`` (each cell's corners,
    first axis major, as :func:`corner_cells` orders them) at cell ``index`` ``(B, P)``
    (float, exact below 2^24), ``fractions`` the ``d`` positions ``(B, P)`` in the cell.

    One gather per pixel: ONNX Runtime's gather costs per index, 5x less so than eight
    indices of RGB rows; then the corners weighted and summed."""
    weight = [torch.ones_like(index)]
    for f in fractions:
        weight = [w * g for w in weight for g in (1 - f, f)]
    return (cells[:, index.long()] * torch.stack(weight, -1)).sum(-1)


def _table_lookup(table: torch.Tensor, cos_v: torch.Tensor, roughness: torch.Tensor):
    """Bilinear read of :func:`albedo_table` ``(S, S)`` at ``cos_v`` and ``roughness``
    ``(B, P)`` each (clamped to the table)."""
    size = table.shape[0]
    # Each cell's four corners together (in the shipped graph a constant ONNX Runtime folds).
    corners = [table[di : size - 1 + di, dj : size - 1 + dj] for di in (0, 1) for dj in (0, 1)]
    cells = torch.stack(corners, -1).reshape(1, -1, 4)
    x = cos_v.clamp(0.0, 1.0) * (size - 1)
    y = roughness.clamp(0.0, 1.0) * (size - 1)
    i0 = x.floor().clamp(max=size - 2)
    j0 = y.floor().clamp(max=size - 2)
    return _interpolate(cells, i0 * (size - 1) + j0, (x - i0, y - j0))[0]


def _map_lookup(cells: torch.Tensor, dirs: torch.Tensor, roughness: torch.Tensor):
    """Trilinear read ``(B, 3, P)`` of prefiltered maps as :func:`corner_cells` ``(B, 3,
    L - 1, h + 1, 2h + 1, 8)`` at unit ``dirs`` ``(B, 3, P)`` (channels first, see
    :func:`specular_shading`): bilinear between texel centres (wrapping in azimuth, clamped
    at the poles) and linear in ``roughness`` ``(B, P)`` between the levels."""
    batch, _, steps, rows, cols, _ = cells.shape
    levels, h, w = steps + 1, rows - 1, cols - 1
    dx, dy, dz = dirs.unbind(1)
    # Texel coordinates of the padded maps (centres at integers): row 1 is the first row,
    # column 1 the first column (azimuth 0, -z; atan2(-x, z) is the azimuth less pi).
    y = torch.arccos(dy.clamp(-1.0, 1.0)) * (h / math.pi) + 0.5
    x = torch.atan2(-dx, dz) * (w / (2 * math.pi)) + (w / 2 + 0.5)
    s = roughness.clamp(0.0, 1.0) * (levels - 1)
    r0, c0 = y.floor(), x.floor()
    k0 = s.floor().clamp(max=levels - 2)
    images = torch.arange(batch, dtype=dirs.dtype, device=dirs.device)[:, None] * steps
    index = ((images + k0) * rows + r0) * cols + c0  # (B, P)
    flat = cells.transpose(0, 1).reshape(3, -1, 8)
    return _interpolate(flat, index, (s - k0, y - r0, x - c0)).transpose(0, 1)


def light_specular(
    normals: torch.Tensor, view_dirs: torch.Tensor, alpha: torch.Tensor, lights: torch.Tensor
) -> torch.Tensor:
    """``S_S`` ``(B, 3, P)`` of the disk lights ``(B, K, LIGHT_COLUMNS)``
    (:func:`bright_lights`) alone: per light, its power x ``D(h) G(v, l) / (4 n.v)`` at its
    direction, ``D`` widened by its radius (module docstring); unit ``normals``,
    ``view_dirs`` ``(B, 3, P)`` (channels first), GGX width ``alpha`` ``(B, P)``.

    The ``(B, K, P)`` terms are written for few operations (each is one pass over every
    light and pixel): ``G1(c) = 2 c / (c + sqrt(a^2 + (1 - a^2) c^2))``, Smith's form of
    :func:`neurender.ndr.shading.smith_g1`; ``D`` needs no clamp where ``n.l`` and ``n.v``
    are positive (then ``n.h`` is)."""
    dirs, power, radius = lights[..., 0:3], lights[..., 3:6], lights[..., 6:7]
    n_dot_l = dirs @ normals  # (B, K, P)
    v_dot_l = dirs @ view_dirs
    n_dot_v = dot_components(normals.unbind(1), view_dirs.unbind(1))[:, None]  # (B, 1, P)
    # n.h with h = (l + v) / |l + v| and |l + v|^2 = 2 + 2 v.l: no (B, K, 3, P) temporaries.
    cos_h = (n_dot_l + n_dot_v) / torch.sqrt((2 + 2 * v_dot_l).clamp(min=1e-12))
    a2 = (alpha * alpha)[:, None]  # (B, 1, P)
    widened = a2 + radius * radius / 8  # alpha'^2
    denominator = cos_h * cos_h * (widened - 1) + 1
    d = widened / (denominator * denominator)  # pi D(h)
    g_l = n_dot_l / (n_dot_l + torch.sqrt(a2 + (1 - a2) * (n_dot_l * n_dot_l)))  # G1(l) / 2
    c_v = n_dot_v.clamp(1e-7, 1.0)
    g_v = 1 / (c_v + torch.sqrt(a2 + (1 - a2) * (c_v * c_v)))  # G1(v) / (2 n.v)
    # D G1(l) G1(v) / (4 n.v) = (pi D) (G1(l) / 2) (G1(v) / (2 n.v)) / pi
    view = torch.where(n_dot_v > 0, g_v / math.pi, 0.0)
    brdf = torch.where(n_dot_l > 0, d * g_l, 0.0) * view
    return power.transpose(1, 2) @ brdf


def specular_shading(
    normals: torch.Tensor,
    view_dirs: torch.Tensor,
    alpha: torch.Tensor,
    cells: torch.Tensor,
    table: torch.Tensor,
    lights: torch.Tensor,
) -> torch.Tensor:
    """``S_S`` ``(B, 3, P)``: the lights (:func:`light_specular`) and the rest of the map by
    the split sum (module docstring): unit ``normals`` and ``view_dirs`` ``(B, 3, P)``
    (towards the eye), GGX width ``alpha`` ``(B, P)``, the prefiltered maps of the map
    without its lights as :func:`corner_cells` ``(B, 3, L - 1, h + 1, 2h + 1, 8)``,
    :func:`albedo_table` and the lights ``(B, K, LIGHT_COLUMNS)``; 0 where ``n.v <= 0``.

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
    radiance = _map_lookup(cells, dominant, roughness)
    albedo = _table_lookup(table.to(normals.dtype), cos_v, roughness)
    rest = torch.where(cos_v > 0, albedo, 0.0)[:, None] * radiance
    return rest + light_specular(normals, view_dirs, alpha, lights)


class MapLighting(NamedTuple):
    """What the fast shading reads of one map, made once per map (:func:`lighting`),
    float64; a batch of them stacks each field (the lights by :func:`stack_lights`)."""

    #: ``(25, 3)`` the map's 5-band SH (what the network's light input is made of).
    coefficients: torch.Tensor
    #: ``(18, 3)`` ``S_D`` of the map less its lights (:func:`diffuse_polynomial`).
    irradiance: torch.Tensor
    #: ``(3, L - 1, h + 1, 2h + 1, 8)`` the prefiltered maps of its coarse copy less its
    #: lights as :func:`corner_cells`.
    cells: torch.Tensor
    #: ``(K, LIGHT_COLUMNS)`` its bright texels as lights (:func:`bright_lights`).
    lights: torch.Tensor


def map_lighting(coefficients: torch.Tensor, maps: torch.Tensor, lights: torch.Tensor):
    """The :class:`MapLighting` of a map's SH ``coefficients`` ``(25, 3)``, the prefiltered
    maps ``(L, h, 2h, 3)`` of its coarse copy less its ``lights`` ``(K,
    LIGHT_COLUMNS)``."""
    irradiance = diffuse_polynomial(coefficients, lights.to(coefficients.dtype))
    return MapLighting(coefficients, irradiance, corner_cells(maps), lights)


def lighting(environment: np.ndarray, coarse: np.ndarray) -> MapLighting:
    """The fast shading's lighting of one map ``environment`` ``(H, 2H, 3)``, float64: its
    SH, and the prefiltered maps of its downsampled copy ``coarse`` ``(h, 2h, 3)`` less its
    bright texels, which become lights (:func:`bright_lights`)."""
    coefficients = torch.from_numpy(sh.project_latlong(environment, SH_BANDS))
    lights, rest = bright_lights(environment, coarse)
    return map_lighting(coefficients, prefilter(rest), lights)


def prefiltered_shading(
    normals: torch.Tensor, view_dirs: torch.Tensor, alpha: torch.Tensor, light: MapLighting
) -> tuple[torch.Tensor, torch.Tensor]:
    """``S_D`` and ``S_S`` ``(P, 3)`` for ``P`` points under one map's ``light``
    (:func:`lighting`): the counterpart of :func:`neurender.ndr.shading.coarse_shading`.

    Args:
        normals, view_dirs: ``(P, 3)`` unit vectors (view_dir points to the eye).
        alpha: ``(P,)`` GGX width.
        light: the map's :class:`MapLighting`.
    """
    dtype = normals.dtype
    lights = light.lights.to(dtype)
    s_d = diffuse_shading(normals.T, light.irradiance.to(dtype), lights).T
    s_s = specular_shading(
        normals.T[None],
        view_dirs.T[None],
        alpha[None].to(dtype),
        light.cells[None].to(dtype),
        albedo_table(),
        lights[None],
    )[0].T
    return s_d, s_s
