"""Unseen deformations of an object's mean shape, and the baselines that need no learning
(does a network learn how geometry shadows itself, or the training animation?).

Every family deforms the mean training shape (a geometry image ``(n, n, 3)``, world
units) in a way no training split contains, with a ``strength`` in [0, 1] from mild to
strong (0 gives the mean shape back exactly); sizes are relative to the mean shape's
bounding-box diagonal ``D``, so they mean the same for every object:

* ``normal_noise``: a smooth random displacement field along the normals (white noise
  blurred over an eighth of the grid), its largest value ``0.08 D x strength``;
* ``bumps``: 3-5 Gaussian bumps and dents along the normals, up to ``0.1 D x strength`` high;
* ``bend``: the shape bent about an axis through its centre (a random in-plane direction)
  until its ends turn by ``90 deg x strength``;
* ``twist``: a twist about an in-plane axis through the centre, ``90 deg x strength``
  from one end to the other;
* ``rotation``: a rigid rotation about a random axis through the centre by ``60 deg x
  strength`` (its transfer changes only because the SH are world-frame);
* ``extrapolation`` (objects with blendshapes): blendshape weights moved from the mean
  training weights along a random direction to up to ``1.5 x strength`` per weight
  (training weights lie in [0, 1], so strong ones leave that range).

Each frame is deterministic from ``(seed, family, index)`` through
:func:`neurender.rng.stable_seed`; strengths of one index share the random draws, so a
family's frames at growing strength are the same deformation, growing.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.ndimage
from scipy.spatial.transform import Rotation

from neurender.geometry import grid_normals
from neurender.prt import unshadowed
from neurender.rng import stable_seed

#: Families that need only the mean shape.
GEOMETRIC = ("normal_noise", "bumps", "bend", "twist", "rotation")
#: Every family; ``extrapolation`` needs the object's blendshapes.
FAMILIES = (*GEOMETRIC, "extrapolation")


def _diagonal(positions: np.ndarray) -> float:
    p = positions.reshape(-1, 3)
    return float(np.linalg.norm(p.max(0) - p.min(0)))


def _frame_axes(mean: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """The centre ``(3,)`` and a random unit axis ``(3,)`` in the shape's dominant plane
    (its two leading principal directions)."""
    p = mean.reshape(-1, 3)
    centre = p.mean(0)
    _, _, vt = np.linalg.svd(p - centre, full_matrices=False)
    angle = rng.uniform(0, 2 * math.pi)
    return centre, math.cos(angle) * vt[0] + math.sin(angle) * vt[1]


def _smooth_field(n: int, rng: np.random.Generator) -> np.ndarray:
    """``(n, n)`` smooth random field with largest absolute value 1."""
    field = scipy.ndimage.gaussian_filter(rng.normal(size=(n, n)), n / 8, mode="reflect")
    return field / max(float(np.abs(field).max()), 1e-12)


def _bumps(n: int, rng: np.random.Generator) -> np.ndarray:
    """``(n, n)`` sum of 3-5 Gaussian bumps and dents of height up to 1."""
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    field = np.zeros((n, n))
    for _ in range(int(rng.integers(3, 6))):
        ci, cj = rng.uniform(0.15, 0.85, 2) * n
        width = rng.uniform(0.04, 0.1) * n
        height = rng.uniform(0.5, 1.0) * rng.choice([-1.0, 1.0])
        field += height * np.exp(-((i - ci) ** 2 + (j - cj) ** 2) / (2 * width**2))
    return field


def _bend(p: np.ndarray, centre: np.ndarray, axis: np.ndarray, angle: float) -> np.ndarray:
    """Bend about the in-plane ``axis``: coordinate ``s`` along the perpendicular in-plane
    direction maps onto a circular arc whose ends (``|s| = s_max``) turn by ``angle``."""
    q = p - centre
    _, _, vt = np.linalg.svd(q, full_matrices=False)
    normal = vt[2]
    across = np.cross(normal, axis)
    s, h = q @ across, q @ normal
    s_max = max(float(np.abs(s).max()), 1e-12)
    if abs(angle) < 1e-12:
        return p.copy()
    radius = s_max / angle
    theta = s / radius
    new_s = (radius - h) * np.sin(theta)
    new_h = radius - (radius - h) * np.cos(theta)
    rest = q - np.outer(s, across) - np.outer(h, normal)
    return centre + rest + np.outer(new_s, across) + np.outer(new_h, normal)


def _twist(p: np.ndarray, centre: np.ndarray, axis: np.ndarray, angle: float) -> np.ndarray:
    """Rotate each point about ``axis`` (through ``centre``) by ``angle`` times its
    coordinate along the axis over the largest one (a linear twist, ends +-angle/2)."""
    q = p - centre
    t = q @ axis
    t_max = max(float(np.abs(t).max()), 1e-12)
    rot = Rotation.from_rotvec(np.outer(0.5 * angle * t / t_max, axis))
    return centre + rot.apply(q)


def deform(
    mean: np.ndarray,
    family: str,
    strength: float,
    seed: int,
    index: int = 0,
    deltas: np.ndarray | None = None,
) -> np.ndarray:
    """One unseen deformation of the mean shape.

    Args:
        mean: ``(n, n, 3)`` mean training geometry image.
        family: one of :data:`FAMILIES`.
        strength: in [0, 1]; 0 gives ``mean`` exactly.
        seed, index: the random draws come from ``stable_seed(seed, family, index)``.
        deltas: ``(K, n, n, 3)`` blendshape displacements (``extrapolation`` only; the
            blendshape model is linear, so moving the weights by ``w`` moves the mean
            shape by ``sum_k w_k deltas_k``).

    Returns:
        ``(n, n, 3)`` float64 positions on the same grid.
    """
    if family not in FAMILIES:
        raise ValueError(f"unseen-deformation family {family!r}: expected one of {FAMILIES}")
    if not 0.0 <= strength <= 1.0:
        raise ValueError(f"strength {strength}: expected a value in [0, 1]")
    mean = np.asarray(mean, np.float64)
    n = mean.shape[0]
    rng = np.random.default_rng(stable_seed(seed, family, index))
    diag = _diagonal(mean)
    flat = mean.reshape(-1, 3)
    if family in ("normal_noise", "bumps"):
        field = _smooth_field(n, rng) if family == "normal_noise" else _bumps(n, rng)
        height = (0.08 if family == "normal_noise" else 0.1) * diag * strength
        return mean + height * field[..., None] * grid_normals(mean)
    if family == "bend":
        centre, axis = _frame_axes(mean, rng)
        return _bend(flat, centre, axis, 0.5 * math.pi * strength).reshape(mean.shape)
    if family == "twist":
        centre, axis = _frame_axes(mean, rng)
        return _twist(flat, centre, axis, 0.5 * math.pi * strength).reshape(mean.shape)
    if family == "rotation":
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        centre = flat.mean(0)
        rot = Rotation.from_rotvec(axis * math.radians(60.0) * strength)
        return (centre + rot.apply(flat - centre)).reshape(mean.shape)
    if deltas is None or len(deltas) == 0:
        raise ValueError("family 'extrapolation' needs the object's blendshapes (deltas)")
    step = extrapolation_step(strength, seed, index, len(deltas))
    return mean + np.einsum("k,kijc->ijc", step, np.asarray(deltas, np.float64))


def extrapolation_step(strength: float, seed: int, index: int, count: int) -> np.ndarray:
    """``(count,)`` blendshape weights that the ``extrapolation`` frame ``index`` adds to
    the mean training weights (its shape parameters are ``mean weights + step``): a
    random direction scaled to ``1.5 x strength`` in its largest weight."""
    rng = np.random.default_rng(stable_seed(seed, "extrapolation", index))
    direction = rng.uniform(-1.0, 1.0, count)
    direction /= max(float(np.abs(direction).max()), 1e-12)
    return 1.5 * strength * direction


def families_for(has_blendshapes: bool) -> tuple[str, ...]:
    """The families an object supports."""
    return FAMILIES if has_blendshapes else GEOMETRIC


def unshadowed_baseline(positions: np.ndarray, n_bands: int) -> np.ndarray:
    """``(F, K, n, n)`` unshadowed diffuse transfer of frames ``(F, n, n, 3)`` (the normals
    of their grid meshes, as the ground truth's)."""
    t = np.stack([unshadowed.diffuse(grid_normals(p), n_bands) for p in positions])
    return np.ascontiguousarray(np.moveaxis(t, -1, 1), np.float32)


def unshadowed_glossy_baseline(positions: np.ndarray, coeffs: np.ndarray) -> np.ndarray:
    """``(F, 3 K, n, n)`` unshadowed glossy transferred radiance of frames ``(F, n, n, 3)``
    under the light of :func:`neurender.prt.unshadowed.glossy_polynomial`'s ``coeffs``
    (colour-major, as :meth:`neurender.prt.frames.Split.targets`)."""
    t = np.stack([unshadowed.glossy(grid_normals(p), coeffs) for p in positions])
    return np.ascontiguousarray(np.moveaxis(t, -1, 1), np.float32)


def _occluded(positions: np.ndarray, n_bands: int, light: np.ndarray | None) -> np.ndarray:
    """:func:`neurender.prt.disk_occlusion.occluded_transfer` ``(F, C, n, n)`` of frames
    ``(F, n, n, 3)`` with their grid normals, at the default grid (the shadowing variant's)."""
    import torch  # here: the DAG reads this module's families without torch

    from neurender.prt.disk_occlusion import DEFAULT_GRID, occluded_transfer

    normals = np.stack([grid_normals(p) for p in positions])
    x = torch.from_numpy(
        np.ascontiguousarray(
            np.moveaxis(np.concatenate([positions, normals], -1), -1, 1), np.float64
        )
    )
    with torch.no_grad():
        lit = None if light is None else torch.from_numpy(np.ascontiguousarray(light, np.float64))
        return occluded_transfer(x, n_bands, DEFAULT_GRID, lit).numpy()


def disk_occlusion_baseline(positions: np.ndarray, n_bands: int) -> np.ndarray:
    """``(F, K, n, n)``: :func:`unshadowed_baseline` minus what the frames' own elements
    occlude as disks (:mod:`neurender.prt.disk_occlusion`; no rays, no learning)."""
    occluded = _occluded(positions, n_bands, None)
    return (unshadowed_baseline(positions, n_bands) - occluded).astype(np.float32)


def disk_occlusion_glossy_baseline(
    positions: np.ndarray, coeffs: np.ndarray, light: np.ndarray
) -> np.ndarray:
    """``(F, 3 K, n, n)``: :func:`unshadowed_glossy_baseline` minus the disks' glossy
    estimate under ``light`` ``(K, 3)`` (whose ``coeffs`` those are)."""
    occluded = _occluded(positions, math.isqrt(light.shape[0]), light)
    return (unshadowed_glossy_baseline(positions, coeffs) - occluded).astype(np.float32)


def static_baseline(mean_transfer: np.ndarray, frames: int) -> np.ndarray:
    """``(F, C, n, n)``: the mean shape's transfer ``(C, n, n)`` for every frame (classic PRT
    of one pose, never updated)."""
    return np.repeat(np.asarray(mean_transfer, np.float32)[None], frames, axis=0)
