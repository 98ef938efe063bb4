"""Deformation sequences applied to a geometry-image grid mesh S_R (paper 3.1, 3.2.2).

Every function returns positions ``(frames, n, n, 3)`` on the same grid, so pixel
``(i, j)`` is the same surface point in every frame. Time is measured in frames.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.ndimage


def smooth_walk(
    frames: int, dims: int, rng: np.random.Generator, period: float = 60.0
) -> np.ndarray:
    """Smooth random walk in ``[0, 1]^dims``: a sum of random sinusoids, squashed.

    Returns:
        ``(frames, dims)`` values; about one oscillation per ``period`` frames.
    """
    t = np.arange(frames)[:, None, None]
    k = 4  # sinusoids per dimension
    freq = rng.uniform(0.5, 2.0, (1, dims, k)) * 2.0 * math.pi / period
    phase = rng.uniform(0, 2 * math.pi, (1, dims, k))
    amp = rng.uniform(0.5, 1.0, (1, dims, k))
    s = (amp * np.sin(freq * t + phase)).sum(-1) / np.sqrt((amp**2).sum(-1) / 2.0)
    return 0.5 + 0.5 * np.tanh(s)


def apply_blendshapes(rest: np.ndarray, deltas: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Linear blendshape model ``S = S_0 + sum_k w_k D_k``.

    Args:
        rest: ``(n, n, 3)`` neutral geometry image.
        deltas: ``(K, n, n, 3)`` full-weight displacements.
        weights: ``(frames, K)``.

    Returns:
        ``(frames, n, n, 3)``.
    """
    return rest[None] + np.einsum("fk,kijc->fijc", weights, deltas)


def bernstein(degree: int, t: np.ndarray) -> np.ndarray:
    """Bernstein basis ``B_{i,d}(t)``, ``(..., degree + 1)`` for ``t`` ``(...)`` in [0, 1]."""
    i = np.arange(degree + 1)
    binom = np.array([math.comb(degree, k) for k in i], dtype=np.float64)
    t = np.asarray(t, dtype=np.float64)[..., None]
    return binom * t**i * (1.0 - t) ** (degree - i)


def ffd(
    points: np.ndarray, lower: np.ndarray, upper: np.ndarray, control: np.ndarray
) -> np.ndarray:
    """Sederberg-Parry free-form deformation with a Bernstein lattice.

    Args:
        points: ``(N, 3)`` positions inside the box ``[lower, upper]``.
        lower, upper: ``(3,)`` corners of the lattice box.
        control: ``(l+1, m+1, n+1, 3)`` control-point positions; the undeformed lattice
            (:func:`ffd_lattice`) reproduces ``points`` exactly.

    Returns:
        ``(N, 3)`` deformed positions.
    """
    stu = (points - lower) / (upper - lower)
    bs = [bernstein(control.shape[a] - 1, stu[:, a]) for a in range(3)]
    return np.einsum("ni,nj,nk,ijkc->nc", bs[0], bs[1], bs[2], control)


def ffd_lattice(lower: np.ndarray, upper: np.ndarray, shape: tuple[int, int, int]) -> np.ndarray:
    """Undeformed control points ``(*shape, 3)`` evenly spaced in the box."""
    axes = [np.linspace(lower[a], upper[a], shape[a]) for a in range(3)]
    return np.stack(np.meshgrid(*axes, indexing="ij"), -1)


def lattice_displacements(
    frames: int,
    shape: tuple[int, int, int],
    amplitude: float,
    rng: np.random.Generator,
    period: float = 50.0,
) -> np.ndarray:
    """Smoothly moving control-point offsets ``(frames, *shape, 3)`` of size ~``amplitude``."""
    walk = smooth_walk(frames, int(np.prod(shape)) * 3, rng, period)
    return (2.0 * walk - 1.0).reshape((frames, *shape, 3)) * amplitude


def simulate_cloth(
    rest: np.ndarray,
    frames: int,
    rng: np.random.Generator,
    sim_side: int = 32,
    substeps: int = 6,
    iterations: int = 10,
    warmup: int = 40,
) -> np.ndarray:
    """Position-based dynamics (Mueller et al. 2007) of a square cloth.

    The cloth (a flat square geometry image, z = 0) is turned horizontal (into the x-z
    plane, y up), pinned at two corners, and falls under gravity onto a sphere while a
    gusting wind blows. Constraints: stretch (grid edges), shear (diagonals) and bending
    (distance two), projected Jacobi-style; sphere collision. The simulation runs on a
    ``sim_side^2`` particle grid and is upsampled with cubic splines to the geometry image,
    which keeps the cost independent of ``n``.

    Args:
        rest: ``(n, n, 3)`` flat cloth geometry image.
        frames: frames to record (one per 1/30 s) after ``warmup`` frames.
        rng: wind gusts and the sphere's position come from it.

    Returns:
        ``(frames, n, n, 3)``.
    """
    n = rest.shape[0]
    m = min(sim_side, n)
    coarse = np.stack([scipy.ndimage.zoom(rest[..., c], m / n, order=1) for c in range(3)], -1)[
        :m, :m
    ]
    # rest geometry image: x right, y up in the sheet -> lay it in the x-z plane at height 1.
    x = np.stack([coarse[..., 0], np.full((m, m), 1.0), -coarse[..., 1]], -1).reshape(-1, 3)
    x0 = x.copy()
    v = np.zeros_like(x)
    idx = np.arange(m * m).reshape(m, m)
    pairs = _constraint_pairs(m)
    rest_len = np.linalg.norm(x0[pairs[:, 0]] - x0[pairs[:, 1]], axis=1)
    pinned = np.array([idx[-1, 0], idx[-1, -1]])  # the two corners of the far edge
    centre = np.array([rng.uniform(-0.25, 0.25), 0.0, rng.uniform(-0.2, 0.2)])
    radius = 0.55
    dt = 1.0 / 30.0 / substeps
    gravity = np.array([0.0, -9.81, 0.0])
    gust_freq = rng.uniform(0.3, 1.2, 3) * 2 * math.pi
    gust_phase = rng.uniform(0, 2 * math.pi, 3)
    wind_dir = rng.normal(size=3)
    wind_dir[1] = 0.2 * abs(wind_dir[1])

    def wind(time: float) -> np.ndarray:
        return 3.0 * (wind_dir + np.sin(gust_freq * time + gust_phase))

    out = np.empty((frames, n, n, 3))
    ends = np.concatenate([pairs[:, 0], pairs[:, 1]])
    counts = np.bincount(ends, minlength=m * m)[:, None].astype(np.float64)
    for frame in range(warmup + frames):
        for sub in range(substeps):
            time = (frame * substeps + sub) * dt
            normals = _grid_normals_coarse(x.reshape(m, m, 3)).reshape(-1, 3)
            w = wind(time)
            force = gravity + normals * (normals @ w)[:, None]  # wind pushes along the normal
            v = 0.995 * v + dt * force
            p = x + dt * v
            for _ in range(iterations):
                p += 1.5 * _distance_corrections(p, pairs, rest_len, ends) / counts
                p = _push_out_of_sphere(p, centre, radius * 1.02)
                p[pinned] = x0[pinned]
            v = (p - x) / dt
            x = p
        if frame >= warmup:
            grid = x.reshape(m, m, 3)
            fine = np.stack(
                [scipy.ndimage.zoom(grid[..., c], n / m, order=3) for c in range(3)], -1
            )
            out[frame - warmup] = _push_out_of_sphere(fine.reshape(-1, 3), centre, radius).reshape(
                n, n, 3
            )
    return out


def _constraint_pairs(m: int) -> np.ndarray:
    """Particle pairs ``(P, 2)`` of an ``m x m`` grid held at their rest distance: stretch
    (grid edges), shear (diagonals) and bending (distance two)."""
    idx = np.arange(m * m).reshape(m, m)
    pairs = []
    for di, dj in ((0, 1), (1, 0), (1, 1), (1, -1), (0, 2), (2, 0)):
        a = idx[max(0, -di) : m - max(0, di), max(0, -dj) : m - max(0, dj)]
        b = idx[max(0, di) : m + min(0, di) or None, max(0, dj) : m + min(0, dj) or None]
        pairs.append(np.stack([a.ravel(), b.ravel()], 1))
    return np.concatenate(pairs)


def _distance_corrections(
    p: np.ndarray, pairs: np.ndarray, rest_len: np.ndarray, ends: np.ndarray
) -> np.ndarray:
    """The summed moves ``(N, 3)`` that restore every pair's rest length, half to each end
    (divided by each particle's pair count, a Jacobi step)."""
    d = p[pairs[:, 1]] - p[pairs[:, 0]]
    length = np.linalg.norm(d, axis=1, keepdims=True)
    corr = 0.5 * (1.0 - rest_len[:, None] / np.maximum(length, 1e-12)) * d
    return np.stack(
        [np.bincount(ends, np.concatenate([corr[:, c], -corr[:, c]]), len(p)) for c in range(3)],
        1,
    )


def _push_out_of_sphere(p: np.ndarray, centre: np.ndarray, radius: float) -> np.ndarray:
    d = p - centre
    dist = np.linalg.norm(d, axis=1, keepdims=True)
    inside = dist < radius
    return np.where(inside, centre + d / np.maximum(dist, 1e-12) * radius, p)


def _grid_normals_coarse(p: np.ndarray) -> np.ndarray:
    du = np.gradient(p, axis=1)
    dv = np.gradient(p, axis=0)
    nrm = np.cross(du, dv)
    return nrm / np.maximum(np.linalg.norm(nrm, axis=-1, keepdims=True), 1e-12)
