"""Real spherical harmonics (bands l = 0..4) for numpy arrays and torch tensors.

Convention (used everywhere in neurender):

* Real SH ``y_k`` with flat index ``k = l (l + 1) + m``, ``-l <= m <= l``; band ``l`` has
  ``2 l + 1`` functions and ``n_bands`` bands have ``n_bands**2`` coefficients.
* Orthonormal on the unit sphere: ``integral y_i y_j dw = delta_ij``.
* Condon-Shortley phase included, exactly as the polynomial table in Sloan,
  "Stupid Spherical Harmonics (SH) Tricks" (2008), Appendix A2: e.g.
  ``y_1^-1 = -0.4886 y``, ``y_1^0 = 0.4886 z``, ``y_1^1 = -0.4886 x``. Equivalently
  ``y_l^m = sqrt(2) Re Y_l^m`` (m > 0), ``sqrt(2) Im Y_l^|m|`` (m < 0), ``Y_l^0`` (m = 0)
  with ``Y_l^m`` the complex SH of scipy (which carries the phase).
* SH are functions of unit direction vectors ``(x, y, z)`` in the world frame; ``z`` is the
  polar axis of the polynomials. Nothing here assumes which world axis is "up".

Lat-long (equirectangular) maps follow Mitsuba's ``envmap`` directions, y up, with texel
centres (Mitsuba puts its rows on a grid through both poles: hand a map over through
:func:`neurender.mitsuba_setup.envmap_rows`): pixel ``(row, col)`` of an ``(H, W)`` map
has ``u = (col + 0.5) / W``, ``v = (row + 0.5) / H`` and direction
``(sin(theta) sin(phi), cos(theta), -sin(theta) cos(phi))`` with ``theta = pi v``,
``phi = 2 pi u`` (so ``u = atan2(x, -z) / 2 pi``, ``v = acos(y) / pi``).
Radiance is linear (scene-referred) RGB.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # torch is imported only by callers that pass tensors (the DAG never does)
    import torch

MAX_BANDS = 5

# Normalisation constants of Sloan's table, named by band and |m| so the polynomial
# table below reads like the paper's.
_C00 = 0.5 / math.sqrt(math.pi)
_C1 = math.sqrt(3.0 / (4.0 * math.pi))
_C22 = 0.5 * math.sqrt(15.0 / math.pi)
_C21 = 0.5 * math.sqrt(15.0 / math.pi)
_C20 = 0.25 * math.sqrt(5.0 / math.pi)
_C33 = 0.25 * math.sqrt(35.0 / (2.0 * math.pi))
_C32 = 0.5 * math.sqrt(105.0 / math.pi)
_C31 = 0.25 * math.sqrt(21.0 / (2.0 * math.pi))
_C30 = 0.25 * math.sqrt(7.0 / math.pi)
_C44 = 0.75 * math.sqrt(35.0 / math.pi)
_C43 = 0.75 * math.sqrt(35.0 / (2.0 * math.pi))
_C42 = 0.75 * math.sqrt(5.0 / math.pi)
_C41 = 0.75 * math.sqrt(5.0 / (2.0 * math.pi))
_C40 = 3.0 / 16.0 * math.sqrt(1.0 / math.pi)

#: Projection of the clamped cosine ``max(cos(theta), 0)`` onto the zonal ``y_l^0``
#: (l = 0..4): sqrt(pi)/2, sqrt(pi/3), sqrt(5 pi)/8, 0, -sqrt(pi)/16.
CLAMPED_COSINE_ZONAL = (
    math.sqrt(math.pi) / 2.0,
    math.sqrt(math.pi / 3.0),
    math.sqrt(5.0 * math.pi) / 8.0,
    0.0,
    -math.sqrt(math.pi) / 16.0,
)


def check_bands(n_bands: int) -> None:
    if not 1 <= n_bands <= MAX_BANDS:
        raise ValueError(f"n_bands={n_bands}: expected 1..{MAX_BANDS} (bands l = 0..4)")


def sh_index(l: int, m: int) -> int:  # noqa: E741 - l is the standard name of the band
    """Flat index ``l (l + 1) + m`` of ``y_l^m``."""
    if abs(m) > l:
        raise ValueError(f"|m|={abs(m)} exceeds band l={l}")
    return l * (l + 1) + m


def eval_sh(
    dirs: np.ndarray | torch.Tensor, n_bands: int = 4, axis: int = -1
) -> np.ndarray | torch.Tensor:
    """Evaluate real SH at unit directions.

    Args:
        dirs: ``(..., 3)`` unit vectors, numpy array or torch tensor (any float dtype);
            the components along ``axis`` (e.g. ``-2`` for channels-first ``(..., 3, P)``).
        n_bands: number of bands, 1..5.
        axis: the axis of ``dirs`` holding the components, and of the result holding the
            basis functions.

    Returns:
        ``(..., n_bands**2)`` basis values (along ``axis``), same library, dtype and device
        as ``dirs``.
    """
    check_bands(n_bands)
    if dirs.shape[axis] != 3:
        raise ValueError(f"dirs must have 3 components along axis {axis}, got {tuple(dirs.shape)}")
    if isinstance(dirs, np.ndarray):
        x, y, z = np.moveaxis(dirs, axis, 0)
    else:
        x, y, z = dirs.unbind(axis)
    ys = [_C00 + 0.0 * x]
    if n_bands > 1:
        ys += [-_C1 * y, _C1 * z, -_C1 * x]
    if n_bands > 2:
        x2, y2, z2 = x * x, y * y, z * z
        ys += [
            _C22 * x * y,
            -_C21 * y * z,
            _C20 * (3.0 * z2 - 1.0),
            -_C21 * x * z,
            0.5 * _C22 * (x2 - y2),
        ]
    if n_bands > 3:
        ys += [
            -_C33 * y * (3.0 * x2 - y2),
            _C32 * x * y * z,
            -_C31 * y * (5.0 * z2 - 1.0),
            _C30 * z * (5.0 * z2 - 3.0),
            -_C31 * x * (5.0 * z2 - 1.0),
            0.5 * _C32 * z * (x2 - y2),
            -_C33 * x * (x2 - 3.0 * y2),
        ]
    if n_bands > 4:
        ys += [
            _C44 * x * y * (x2 - y2),
            -_C43 * y * z * (3.0 * x2 - y2),
            _C42 * x * y * (7.0 * z2 - 1.0),
            -_C41 * y * z * (7.0 * z2 - 3.0),
            _C40 * (35.0 * z2 * z2 - 30.0 * z2 + 3.0),
            -_C41 * x * z * (7.0 * z2 - 3.0),
            0.5 * _C42 * (x2 - y2) * (7.0 * z2 - 1.0),
            -_C43 * x * z * (x2 - 3.0 * y2),
            0.25 * _C44 * (x2 * x2 - 6.0 * x2 * y2 + y2 * y2),
        ]
    if isinstance(dirs, np.ndarray):
        return np.stack(ys, axis=axis)
    import torch

    return torch.stack(ys, dim=axis)


def stratified_sphere_directions(n: int, rng: np.random.Generator) -> np.ndarray:
    """Jittered stratified directions, uniform over the sphere.

    The unit square is split into ``sqrt(n) x sqrt(n)`` cells, one jittered sample each,
    and mapped area-preservingly to the sphere (``z = 1 - 2 u``, ``phi = 2 pi v``), so every
    sample carries the same solid angle ``4 pi / n``.

    Args:
        n: number of directions, a perfect square (e.g. 256, 1024).
        rng: numpy random generator (the only source of randomness).

    Returns:
        ``(n, 3)`` float64 unit vectors.
    """
    side = math.isqrt(n)
    if n <= 0 or side * side != n:
        raise ValueError(
            f"direction count {n}: expected a positive perfect square (e.g. 256, 1024)"
        )
    cells = np.stack(np.meshgrid(np.arange(side), np.arange(side), indexing="ij"), -1)
    uv = (cells.reshape(-1, 2) + rng.random((n, 2))) / side
    z = 1.0 - 2.0 * uv[:, 0]
    r = np.sqrt(np.clip(1.0 - z * z, 0.0, None))
    phi = 2.0 * math.pi * uv[:, 1]
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=-1)


def latlong_directions(height: int, width: int) -> tuple[np.ndarray, np.ndarray]:
    """Pixel-centre directions and solid angles of an ``(H, W)`` lat-long map.

    Returns:
        ``dirs``: ``(H, W, 3)`` float64 unit vectors (module convention, y up);
        ``solid_angle``: ``(H, W)`` float64 steradians, summing to ``4 pi`` up to
        discretisation.
    """
    theta = math.pi * (np.arange(height) + 0.5) / height
    phi = 2.0 * math.pi * (np.arange(width) + 0.5) / width
    t, p = np.meshgrid(theta, phi, indexing="ij")
    dirs = np.stack([np.sin(t) * np.sin(p), np.cos(t), -np.sin(t) * np.cos(p)], axis=-1)
    solid_angle = (2.0 * math.pi / width) * (math.pi / height) * np.sin(t)
    return dirs, solid_angle


def project_latlong(image: np.ndarray, n_bands: int = 4) -> np.ndarray:
    """Project a lat-long map onto SH by midpoint quadrature.

    Args:
        image: ``(H, W, C)`` linear radiance (or ``(H, W)`` for one channel).
        n_bands: number of bands.

    Returns:
        ``(n_bands**2, C)`` float64 coefficients ``c_k = integral L(w) y_k(w) dw``
        (``(n_bands**2,)`` for a 2-D input).
    """
    img = np.asarray(image, dtype=np.float64)
    flat = img.ndim == 2
    if flat:
        img = img[..., None]
    if img.ndim != 3:
        raise ValueError(f"lat-long image must be (H, W) or (H, W, C), got {img.shape}")
    dirs, solid_angle = latlong_directions(img.shape[0], img.shape[1])
    basis = eval_sh(dirs, n_bands) * solid_angle[..., None]
    coeffs = basis.reshape(-1, basis.shape[-1]).T @ img.reshape(-1, img.shape[-1])
    return coeffs[:, 0] if flat else coeffs


def reconstruct_latlong(coeffs: np.ndarray, height: int, width: int) -> np.ndarray:
    """Evaluate an SH expansion on an ``(H, W)`` lat-long grid.

    Args:
        coeffs: ``(K,)`` or ``(K, C)`` coefficients, ``K`` a square number of bands.

    Returns:
        ``(H, W)`` or ``(H, W, C)`` float64 values.
    """
    c = np.asarray(coeffs, dtype=np.float64)
    n_bands = math.isqrt(c.shape[0])
    if n_bands * n_bands != c.shape[0]:
        raise ValueError(f"{c.shape[0]} SH coefficients is not a whole number of bands")
    dirs, _ = latlong_directions(height, width)
    return eval_sh(dirs, n_bands) @ c


def rotate_zonal(zonal: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """Coefficients of a zonal (axially symmetric) function rotated to point along ``axis``.

    Uses ``f_l^m = sqrt(4 pi / (2 l + 1)) z_l y_l^m(axis)`` (Sloan 2008, eq. for rotating
    zonal harmonics).

    Args:
        zonal: ``(n_bands,)`` zonal coefficients ``z_l`` of the function around +z.
        axis: ``(..., 3)`` unit vectors.

    Returns:
        ``(..., n_bands**2)`` coefficients.
    """
    zonal = np.asarray(zonal, dtype=np.float64)
    n_bands = zonal.shape[0]
    per_band = [math.sqrt(4.0 * math.pi / (2 * b + 1)) * zonal[b] for b in range(n_bands)]
    scale = np.concatenate([np.full(2 * b + 1, s) for b, s in enumerate(per_band)])
    return eval_sh(np.asarray(axis, dtype=np.float64), n_bands) * scale


def rotation_about_y(angle: float, n_bands: int) -> np.ndarray:
    """The ``(K, K)`` matrix taking coefficients of a function to those of the function
    turned by ``angle`` radians about +y (right-handed): ``c' = R c`` with
    ``f'(w) = f(R_y(-angle) w)``.

    Computed by quadrature of ``R_kj = integral y_k(w) y_j(R_y(-angle) w) dw`` with
    Gauss-Legendre nodes in ``cos(theta)`` and uniform ``phi``, which integrates products
    of two band-limited SH exactly, so the matrix is exact to rounding.
    """
    check_bands(n_bands)
    nodes, weights = np.polynomial.legendre.leggauss(2 * n_bands)
    phis = 2 * math.pi * (np.arange(4 * n_bands) + 0.5) / (4 * n_bands)
    z, phi = np.meshgrid(nodes, phis, indexing="ij")
    r = np.sqrt(1 - z**2)
    dirs = np.stack([r * np.cos(phi), r * np.sin(phi), z], -1).reshape(-1, 3)
    w = (np.repeat(weights, len(phis)) * 2 * math.pi / len(phis))[:, None]
    c, s = math.cos(-angle), math.sin(-angle)
    turn = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
    return (eval_sh(dirs, n_bands) * w).T @ eval_sh(dirs @ turn.T, n_bands)
