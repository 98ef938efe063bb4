"""Ray-traced SH transfer of a deforming surface (Sloan et al. 2002), with Embree.

For a vertex with normal ``n`` and binary visibility ``V(w)``:

* diffuse transfer vector ``t_j = integral V(w) max(n.w, 0) y_j(w) dw`` (no 1/pi: the
  exit radiance of albedo ``rho`` under SH light ``l`` is ``rho / pi * sum_j l_j t_j``);
* glossy transfer matrix ``M_ij = integral y_i(w) V(w) y_j(w) dw`` and the transferred
  incident radiance ``R = M l`` (per colour), which is what we store: ``R_i = integral
  y_i(w) V(w) L(w) dw`` with ``L`` the band-limited light.

``V(w) = 0`` for ``n.w <= 0``: the surface is opaque, so light from below its tangent
plane never reaches the vertex (this also matters for open sheets, whose back would
otherwise see the sky). Above the plane, ``V`` is an Embree occlusion ray from the
vertex offset by ``offset`` along ``n`` (a ray starting exactly on the surface reports
false hits). SH convention: :mod:`neurender.sh`. Integrals are Monte Carlo over jittered
stratified directions, ``4 pi / S`` per sample.
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from embreex import rtcore_scene
from threadpoolctl import threadpool_limits

from neurender import sh
from neurender.geometry import grid_faces, grid_normals
from neurender.raytrace import embree_scene
from neurender.rng import stable_seed


class DirectionSets:
    """``K`` independently jittered stratified direction sets with their SH basis.

    Evaluating the basis once per set (not per vertex) turns the projection into one
    matrix product per set.

    Attributes:
        dirs: ``(K, S, 3)`` float32 unit directions.
        basis: ``(K, S, n_bands**2)`` float32 SH values.
    """

    def __init__(self, count: int, directions: int, n_bands: int, rng: np.random.Generator):
        self.dirs = np.stack(
            [sh.stratified_sphere_directions(directions, rng) for _ in range(count)]
        )
        self.basis = sh.eval_sh(self.dirs, n_bands).astype(np.float32)
        self.dirs = self.dirs.astype(np.float32)

    @property
    def weight(self) -> float:
        """Solid angle per sample, ``4 pi / S``."""
        return 4.0 * math.pi / self.dirs.shape[1]


def upper_hemisphere_rays(
    positions: np.ndarray, normals: np.ndarray, dirs: np.ndarray, offset: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Occlusion rays of vertices ``(N, 3)`` along directions ``(S, 3)`` above the tangent plane.

    Returns:
        ``cos`` ``(N, S)``, ``upper = cos > 0``, and ray origins and directions ``(R, 3)``
        in vertex-major order (sorted by origin).
    """
    cos = normals @ dirs.T
    upper = cos > 0
    # repeat/take are much cheaper than fancy indexing, which would cost as much as tracing.
    origins = np.repeat(positions + offset * normals, upper.sum(1), axis=0)
    return cos, upper, origins, np.take(dirs, np.nonzero(upper)[1], axis=0)


def direction_jobs(
    assignment: np.ndarray, count: int, block: int = 2048
) -> list[tuple[int, np.ndarray]]:
    """Work items ``(set index, vertex rows)``: each set's vertices in blocks of ~``block``."""
    jobs = []
    for s in range(count):
        rows = np.nonzero(assignment == s)[0]
        jobs += [
            (s, part) for part in np.array_split(rows, max(1, len(rows) // block)) if len(part)
        ]
    return jobs


def vertex_transfer(
    scene: rtcore_scene.EmbreeScene,
    positions: np.ndarray,
    normals: np.ndarray,
    dirs: np.ndarray,
    basis: np.ndarray,
    weight: float,
    offset: float,
    light: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray | None, int]:
    """Trace and project the transfer of vertices that share one direction set (one thread).

    Args:
        scene: Embree scene of the mesh (:func:`neurender.raytrace.embree_scene`).
        positions, normals: ``(N, 3)`` float32 vertices and unit normals.
        dirs: ``(S, 3)`` float32 directions; basis: ``(S, K)`` their SH values.
        weight: solid angle per direction (``4 pi / S``).
        offset: origin offset along the normal, world units.
        light: ``(K, 3)`` SH light, or ``None`` to skip glossy.

    Returns:
        diffuse ``(N, K)``, glossy ``(N, 3, K)`` (or ``None``), and the number of rays.
    """
    cos, upper, origins, ray_dirs = upper_hemisphere_rays(positions, normals, dirs, offset)
    missed = scene.run(origins, ray_dirs, query="OCCLUDED") == -1
    vis = np.zeros(cos.shape, np.float32)
    vis[upper] = missed * np.float32(weight)  # V = 0 below the tangent plane
    diffuse = (vis * cos) @ basis
    glossy = None
    if light is not None:
        radiance = basis @ light.astype(np.float32)  # (S, 3) band-limited light per direction
        # R_ck = sum_s V_s L_c(w_s) y_k(w_s): one product with the (S, 3 K) light-weighted basis.
        weighted = (radiance[:, :, None] * basis[:, None, :]).reshape(len(basis), -1)
        glossy = (vis @ weighted).reshape(len(vis), 3, -1)
    return diffuse, glossy, len(origins)


def frame_transfer(
    positions: np.ndarray,
    faces: np.ndarray,
    sets: DirectionSets,
    rng: np.random.Generator,
    offset: float,
    light: np.ndarray | None = None,
    threads: int = 1,
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, int]:
    """Transfer of every vertex of one frame of a deforming geometry image.

    Args:
        positions: ``(n, n, 3)`` geometry image of the frame.
        faces: grid-mesh triangles (:func:`neurender.geometry.grid_faces`).
        sets: direction sets; each vertex draws one at random from ``rng``.
        offset: ray origin offset, world units.
        light: ``(K, 3)`` SH light for the glossy transferred radiance, or ``None``.

    Returns:
        normals ``(n, n, 3)``, diffuse ``(n, n, K)``, glossy ``(n, n, 3, K)`` or ``None``,
        and the number of rays traced.
    """
    n = positions.shape[0]
    p = positions.reshape(-1, 3).astype(np.float32)
    normals = grid_normals(positions).reshape(-1, 3).astype(np.float32)
    assignment = rng.integers(0, sets.dirs.shape[0], len(p))
    scene = embree_scene(p, faces)
    k = sets.basis.shape[-1]
    diffuse = np.empty((len(p), k), np.float32)
    glossy = None if light is None else np.empty((len(p), 3, k), np.float32)

    def block(job: tuple[int, np.ndarray]) -> int:
        # numpy and Embree both release the GIL, so blocks run in parallel end to end.
        s, rows = job
        d, g, rays = vertex_transfer(
            scene, p[rows], normals[rows], sets.dirs[s], sets.basis[s], sets.weight, offset, light
        )
        diffuse[rows] = d
        if glossy is not None:
            glossy[rows] = g
        return rays

    jobs = direction_jobs(assignment, sets.dirs.shape[0])
    # One BLAS thread per worker: OpenBLAS's own threads would fight ours for the cores.
    with threadpool_limits(1, user_api="blas"), ThreadPoolExecutor(max(threads, 1)) as pool:
        rays = sum(pool.map(block, jobs))
    return (
        normals.reshape(n, n, 3),
        diffuse.reshape(n, n, k),
        None if glossy is None else glossy.reshape(n, n, 3, k),
        rays,
    )


def relight_diffuse(transfer: np.ndarray, light: np.ndarray, albedo: float = 1.0) -> np.ndarray:
    """Exit radiance of a Lambertian surface: ``albedo / pi * sum_j l_j t_j``.

    Args:
        transfer: ``(..., K)`` diffuse transfer.
        light: ``(K, 3)`` SH light.

    Returns:
        ``(..., 3)`` linear RGB radiance.
    """
    return albedo / math.pi * transfer @ light


def sample_frame(
    positions: np.ndarray,
    directions: int,
    cfg: dict,
    offset: float,
    light: np.ndarray | None,
    threads: int,
    *seed: object,
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, int]:
    """:func:`frame_transfer` of a geometry image ``(n, n, 3)`` with ``directions`` per
    vertex, its direction sets and their assignment drawn from ``stable_seed(cfg["seed"],
    *seed)`` (``cfg``: ``seed``, ``direction_sets``, ``n_bands``)."""
    rng = np.random.default_rng(stable_seed(cfg["seed"], *seed))
    sets = DirectionSets(cfg["direction_sets"], directions, cfg["n_bands"], rng)
    faces = grid_faces(positions.shape[0])
    return frame_transfer(positions, faces, sets, rng, offset, light, threads)
