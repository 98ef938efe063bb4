"""What a deforming surface occludes, estimated from disks, without rays or learning.

After Bunnell's dynamic ambient occlusion (M. Bunnell, "Dynamic Ambient Occlusion and
Indirect Lighting", GPU Gems 2, ch. 14, Addison-Wesley 2005): the surface is cut into
emitter elements, each a disk of its patch's area; a receiver at ``p`` with normal ``n``
sees element ``e`` at ``q_e`` (vector area ``a_e``) in the direction ``w = (q_e - p) / d``
under the solid angle of a disk of area ``|a_e . w|`` facing it at distance ``d``,
``Omega_e = 2 pi (1 - 1 / sqrt(1 + |a_e . w| / (pi d^2)))``. Both sides of an element
occlude (a cloth is two-sided). The transfer the elements remove is then, in the SH of
:mod:`neurender.sh` and the units of :mod:`neurender.prt.transfer`:

* diffuse ``o_k = sum_e Omega_e max(0, n . w_e) y_k(w_e)`` (the cosine-weighted
  visibility integral of the occluded directions);
* glossy ``o_{c,k} = sum_e Omega_e [n . w_e > 0] L_c(w_e) y_k(w_e)`` for an SH light
  ``L`` (colour-major, as :func:`neurender.prt.unshadowed.glossy`).

The diffuse sum is computed from moments: band ``l`` of the SH is a polynomial of degree
``l`` in ``w``, so ``o_k`` is a fixed linear map (:func:`sh_of_monomials`) of the weighted
sums ``sum_e W_e w_e^a`` over the monomials of degree ``< n_bands``
(:func:`weighted_moments`), which take fewer element-wise operations over the pairs than
the basis at every pair (ONNX Runtime, a 64 x 64 frame: 0.92 ms against 1.61,
``benchmarks/prt_graph.py``). The glossy sum is of degree ``2 (n_bands - 1)`` and keeps
the basis (its moments were slower).

Elements are not depth-sorted, so overlapping occluders are counted twice (Bunnell's
multi-pass correction is not done): the estimate is what a network corrects, not the
answer. Emitters and receivers are the same ``grid x grid`` blocks of the geometry
image (:func:`block_stride`; block means of P, summed vector areas, renormalised mean
normals); the receivers' result is upsampled bilinearly to the image, so the cost is
``grid^4`` pairs at any resolution (65,536 at the default 16). Geometry images
``(B, 3, n, n)``; every operation exports to ONNX, so a shipped graph computes it from
raw P and N.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import torch
import torch.nn.functional as F  # noqa: N812 - the usual name

from neurender import sh
from neurender.geometry import dot_components
from neurender.prt.unshadowed import monomial_exponents, monomial_parent, monomials

#: Blocks per side of the emitters and receivers by default (65,536 pairs).
DEFAULT_GRID = 16


def vector_area(positions: torch.Tensor) -> torch.Tensor:
    """``(B, 3, n, n)`` vector area of each pixel's patch of a geometry image ``(B, 3, n,
    n)``: the cross product of its central differences along the rows and columns
    (one-sided at the borders), in squared world units, along ``dP/du x dP/dv``."""
    padded = F.pad(positions, (1, 1, 1, 1), mode="replicate")
    du = padded[:, :, 1:-1, 2:] - padded[:, :, 1:-1, :-2]
    dv = padded[:, :, 2:, 1:-1] - padded[:, :, :-2, 1:-1]
    # At the borders the difference spans one pixel, not two.
    n = positions.shape[-1]
    span = torch.full((n,), 2.0, dtype=positions.dtype, device=positions.device)
    span[0] = span[-1] = 1.0
    du, dv = du / span, dv / span[:, None]
    ax, ay, az = du.unbind(1)
    bx, by, bz = dv.unbind(1)
    return torch.stack([ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx], 1)


def block_stride(n: int, grid: int) -> int:
    """Pixels per block side of an ``n``-pixel image cut into about ``grid`` blocks per
    side: the largest divisor of ``n`` up to ``n / grid`` (1 where ``n <= grid``), so the
    blocks tile the image (``grid`` of them where ``grid`` divides ``n``)."""
    if grid < 1:
        raise ValueError(f"occlusion grid {grid}: expected at least 1")
    return next(s for s in range(max(1, n // grid), 0, -1) if n % s == 0)


@functools.cache
def sh_of_monomials(n_bands: int) -> np.ndarray:
    """``(M, K)`` float64 ``C`` with ``sh.eval_sh(w, n_bands) = monomials(w, n_bands - 1) @ C``
    for unit vectors ``w`` (:func:`neurender.prt.unshadowed.monomials`; band ``l`` is a
    polynomial of degree ``l``), fitted by least squares at 400 random unit vectors: exact
    to rounding, since the basis lies in the span of the monomials on the sphere."""
    sh.check_bands(n_bands)
    dirs = np.random.default_rng(0).normal(size=(400, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    coeffs, *_ = np.linalg.lstsq(
        monomials(dirs, n_bands - 1), sh.eval_sh(dirs, n_bands), rcond=1e-10
    )
    return coeffs


def weighted_moments(weights: torch.Tensor, w: list[torch.Tensor], degree: int) -> torch.Tensor:
    """``(..., M)`` sums over the last axis of ``weights * x^a y^b z^c``, one per exponent
    of :func:`neurender.prt.unshadowed.monomial_exponents` of ``degree``, for ``weights``
    and the components ``w = [x, y, z]`` all of one shape ``(..., E)``.

    Each product is its parent's (one power less) times one component; those of the top
    degree are summed without being kept."""
    products = {(0, 0, 0): weights}
    sums = []
    for e in monomial_exponents(degree):
        if sum(e) == 0:
            sums.append(weights.sum(-1, keepdim=True))
            continue
        parent, axis = monomial_parent(e)
        product = products[parent] * w[axis]
        if sum(e) < degree:
            products[e] = product
        sums.append(product.sum(-1, keepdim=True))
    return torch.cat(sums, -1)


def occluded_transfer(
    x: torch.Tensor, n_bands: int, grid: int = DEFAULT_GRID, light: torch.Tensor | None = None
) -> torch.Tensor:
    """The transfer the surface's own elements remove (module docstring).

    Args:
        x: ``(B, 6, n, n)`` raw P (world units) and N (unit vectors) images.
        n_bands: SH bands ``K = n_bands^2``.
        grid: blocks per side of the emitters and the receivers.
        light: ``(K, 3)`` SH light for the glossy estimate; None for diffuse.

    Returns:
        ``(B, K, n, n)`` diffuse, or ``(B, 3 K, n, n)`` glossy (colour-major).
    """
    batch, _, n, _ = x.shape
    stride = block_stride(n, grid)
    p, normals = x[:, :3], x[:, 3:6]
    # Per-pair quantities are (B, R, E) images, a vector as its three components, and the
    # basis (B, R, K, E): ONNX Runtime stacks and broadcasts along the contiguous emitter
    # axis many times faster than along a last axis of 3 or K (a (B, R, E, K) basis was
    # most of the shipped graph's time).
    centres = F.avg_pool2d(p, stride).flatten(2).unbind(1)  # 3 x (B, E)
    areas = (F.avg_pool2d(vector_area(p), stride) * stride**2).flatten(2).unbind(1)
    receiver_normals = F.normalize(F.avg_pool2d(normals, stride), dim=1).flatten(2).unbind(1)
    # Receivers are the same blocks as the emitters: v = q_e - p_r, (B, R, E).
    v = [c[:, None, :] - c[:, :, None] for c in centres]
    d2 = dot_components(v, v).clamp_min(1e-12)
    inverse = torch.rsqrt(d2)
    w = [c * inverse for c in v]
    facing = dot_components([a[:, None, :] for a in areas], w).abs()
    omega = 2.0 * math.pi * (1.0 - torch.rsqrt(1.0 + facing / (math.pi * d2)))
    cosine = dot_components([nc[:, :, None] for nc in receiver_normals], w)
    if light is None:
        moments = weighted_moments(omega * cosine.clamp_min(0.0), w, n_bands - 1)  # (B, R, M)
        to_sh = torch.as_tensor(sh_of_monomials(n_bands), dtype=x.dtype, device=x.device)
        blocks = (moments @ to_sh).transpose(1, 2)  # (B, K, R)
    else:
        y = sh.eval_sh(torch.stack(w, 2), n_bands, axis=2)  # (B, R, K, E)
        radiance = light.to(y.dtype).T @ y  # (B, R, 3, E)
        weights = (omega * (cosine > 0).to(omega.dtype))[:, :, None, :] * radiance
        # Sums over the emitters as batched matrix products with y transposed,
        # (B, R, 3, E) @ (B, R, E, K), which ONNX Runtime fuses into one product.
        blocks = (weights @ y.transpose(2, 3)).permute(0, 2, 3, 1).flatten(1, 2)  # (B, 3 K, R)
    side = n // stride
    blocks = blocks.reshape(batch, -1, side, side)
    if side == n:
        return blocks
    return F.interpolate(blocks, size=(n, n), mode="bilinear", align_corners=False)
