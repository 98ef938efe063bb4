"""Unshadowed transfer: what the transfer of :mod:`neurender.prt.transfer` is where nothing
occludes (``V(w) = 1`` above the tangent plane), a function of the normal alone.

* Diffuse: ``t_lm(n) = integral max(n.w, 0) y_lm(w) dw = A_l y_lm(n)`` with
  ``A_l = pi, 2 pi / 3, pi / 4, 0, -pi / 24`` (l = 0..4; Ramamoorthi and Hanrahan 2001),
  i.e. the clamped cosine's zonal coefficients rotated to ``n`` (Funk-Hecke).
* Glossy: ``R_i(n) = integral_{n.w > 0} y_i(w) L(w) dw`` per colour for a fixed SH light
  ``L``. ``y_i L`` has degree at most ``2 (n_bands - 1)``, and the hemisphere's step has
  zero zonal coefficients in every even band above 0, so ``R_i`` is a polynomial of
  degree at most ``2 n_bands - 3`` in ``n`` (odd bands up to that degree plus band 0).
  :func:`glossy_polynomial` finds its coefficients in the monomial basis of
  :func:`monomials` by least squares on exact hemisphere quadratures, so evaluation is
  one matrix product (inside an ONNX graph too).

SH convention and units: :mod:`neurender.sh` and :mod:`neurender.prt.transfer` (no
``1 / pi``). Normals are ``(..., 3)`` unit vectors in the world frame; numpy arrays or
torch tensors (the torch path is what a shipped network computes in its graph).
"""

from __future__ import annotations

import itertools
import math
from typing import TYPE_CHECKING

import numpy as np

from neurender import sh

if TYPE_CHECKING:
    import torch

#: ``A_l`` of the clamped cosine, l = 0..4.
COSINE_LOBE = (math.pi, 2.0 * math.pi / 3.0, math.pi / 4.0, 0.0, -math.pi / 24.0)


def band_scale(n_bands: int) -> np.ndarray:
    """``(n_bands**2,)`` float64: ``A_l`` repeated over the ``2 l + 1`` functions of band l."""
    sh.check_bands(n_bands)
    return np.concatenate([np.full(2 * b + 1, COSINE_LOBE[b]) for b in range(n_bands)])


def diffuse(
    normals: np.ndarray | torch.Tensor, n_bands: int = 4, axis: int = -1
) -> np.ndarray | torch.Tensor:
    """Unshadowed diffuse transfer ``(..., n_bands**2)`` of unit normals ``(..., 3)``,
    same library, dtype and device as ``normals``; components and coefficients along
    ``axis`` (e.g. ``1`` for images ``(B, 3, H, W)`` to ``(B, K, H, W)``)."""
    basis = sh.eval_sh(normals, n_bands, axis)
    shape = [1] * basis.ndim
    shape[axis] = -1
    scale = band_scale(n_bands).reshape(shape)
    if isinstance(basis, np.ndarray):
        return basis * scale.astype(basis.dtype)
    import torch

    return basis * torch.as_tensor(scale, dtype=basis.dtype, device=basis.device)


def monomial_exponents(degree: int) -> list[tuple[int, int, int]]:
    """Exponents ``(a, b, c)`` of ``x^a y^b z^c`` with ``a + b + c <= degree``, in a fixed order."""
    return [
        e
        for total in range(degree + 1)
        for e in itertools.product(range(total + 1), repeat=3)
        if sum(e) == total
    ]


def monomial_parent(exponent: tuple[int, int, int]) -> tuple[tuple[int, int, int], int]:
    """The exponent one power less along the first axis ``exponent`` has, and that axis:
    the monomial of ``exponent`` is its parent's times that component (not for 0, 0, 0)."""
    axis = next(k for k in range(3) if exponent[k])
    return tuple(p - (k == axis) for k, p in enumerate(exponent)), axis


def monomials(
    normals: np.ndarray | torch.Tensor, degree: int, axis: int = -1
) -> np.ndarray | torch.Tensor:
    """``(..., M)`` monomials of :func:`monomial_exponents` at ``normals`` ``(..., 3)``;
    components and monomials along ``axis``. Each is its parent's (one power less) times
    one component: one product per monomial (in an ONNX graph, half the time of powers)."""
    if isinstance(normals, np.ndarray):
        components = list(np.moveaxis(normals, axis, 0))
    else:
        components = list(normals.unbind(axis))
    by_exponent = {}
    for e in monomial_exponents(degree):
        if sum(e) == 0:
            by_exponent[e] = components[0] * 0.0 + 1.0
            continue
        parent, k = monomial_parent(e)
        by_exponent[e] = by_exponent[parent] * components[k]
    cols = list(by_exponent.values())
    if isinstance(normals, np.ndarray):
        return np.stack(cols, axis)
    import torch

    return torch.stack(cols, axis)


def hemisphere_quadrature(normal: np.ndarray, order: int) -> tuple[np.ndarray, np.ndarray]:
    """Directions ``(Q, 3)`` and weights ``(Q,)`` integrating every polynomial of degree
    ``<= order`` exactly over the hemisphere ``n.w > 0`` of one unit ``normal``: Gauss-Legendre
    in ``cos(theta)`` on [0, 1] around ``normal``, uniform in ``phi``."""
    nodes, weights = np.polynomial.legendre.leggauss(order // 2 + 1)
    cos_t, w_t = 0.5 * (nodes + 1.0), 0.5 * weights
    phis = 2.0 * math.pi * np.arange(order + 1) / (order + 1)
    helper = np.array([1.0, 0.0, 0.0]) if abs(normal[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    t = np.cross(normal, helper)
    t /= np.linalg.norm(t)
    b = np.cross(normal, t)
    c, p = np.meshgrid(cos_t, phis, indexing="ij")
    s = np.sqrt(1.0 - c**2)
    dirs = (s * np.cos(p))[..., None] * t + (s * np.sin(p))[..., None] * b + c[..., None] * normal
    w = np.repeat(w_t, len(phis)) * (2.0 * math.pi / len(phis))
    return dirs.reshape(-1, 3), w


def glossy_exact(normals: np.ndarray, light: np.ndarray) -> np.ndarray:
    """Unshadowed glossy transferred radiance ``(N, 3, K)`` of unit normals ``(N, 3)`` under
    SH light ``(K, 3)``, by exact hemisphere quadrature per normal (slow; for fitting)."""
    n_bands = math.isqrt(light.shape[0])
    out = np.empty((len(normals), 3, light.shape[0]))
    for i, n in enumerate(np.asarray(normals, np.float64)):
        dirs, w = hemisphere_quadrature(n, 2 * (n_bands - 1))
        y = sh.eval_sh(dirs, n_bands)  # (Q, K)
        radiance = y @ light  # (Q, 3)
        out[i] = np.einsum("q,qc,qk->ck", w, radiance, y)
    return out


def glossy_degree(n_bands: int) -> int:
    """Polynomial degree of the unshadowed glossy transfer in the normal (module docstring)."""
    return max(2 * n_bands - 3, 1)


def glossy_polynomial(light: np.ndarray, samples: int = 400, seed: int = 0) -> np.ndarray:
    """``(M, 3 K)`` coefficients with ``glossy(n) = monomials(n) @ coeffs`` (colour-major
    like the EXR channels ``G.r.00 .. G.b.{K-1}``), fitted by least squares to
    :func:`glossy_exact` at ``samples`` random unit normals; exact to rounding because the
    function lies in the span of the monomials on the sphere."""
    light = np.asarray(light, np.float64)
    rng = np.random.default_rng(seed)
    normals = rng.normal(size=(samples, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    a = monomials(normals, glossy_degree(math.isqrt(light.shape[0])))
    b = glossy_exact(normals, light).reshape(samples, -1)
    coeffs, *_ = np.linalg.lstsq(a, b, rcond=1e-10)
    return coeffs


def glossy(
    normals: np.ndarray | torch.Tensor, coeffs: np.ndarray | torch.Tensor, axis: int = -1
) -> np.ndarray | torch.Tensor:
    """Unshadowed glossy transferred radiance ``(..., 3 K)`` (colour-major) of unit
    normals ``(..., 3)`` from :func:`glossy_polynomial`'s ``coeffs`` ``(M, 3 K)``;
    components and radiance along ``axis``."""
    degree = next(d for d in range(64) if len(monomial_exponents(d)) == coeffs.shape[0])
    m = monomials(normals, degree, axis)
    axis %= m.ndim
    if axis == m.ndim - 1:
        return m @ coeffs
    # (..., M, rest) to (..., 3 K, rest): one product over the flattened trailing axes.
    flat = m.reshape(*m.shape[: axis + 1], -1)
    return (coeffs.T @ flat).reshape(*m.shape[:axis], coeffs.shape[1], *m.shape[axis + 1 :])
