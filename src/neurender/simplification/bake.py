"""Classic texture baking onto a low-polygon atlas mesh (the Simplygon-style baseline).

For every texel covered by the atlas, the low-poly surface point ``p`` and its interpolated
normal ``n`` are found; a ray along ``+n`` and one along ``-n`` from ``p`` hit the detailed
surface, and the nearer hit gives the detailed normal (and colour). Normals are stored in
Mitsuba's tangent space (see :mod:`neurender.simplification.render`) as ``(m + 1) / 2``. Texels
outside every chart take the value of the nearest covered texel, so bilinear lookups at
chart borders never see undefined data.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np
import scipy.ndimage

from neurender.geometry import vertex_normals
from neurender.raytrace import embree_scene, first_hits
from neurender.simplification.mesh_ops import LowPolyMesh

AttributeFn = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]


@dataclasses.dataclass
class TexelSamples:
    """Covered texels: ``rows, cols (K,)``, ``face (K,)`` and barycentrics ``bary (K, 3)``."""

    rows: np.ndarray
    cols: np.ndarray
    face: np.ndarray
    bary: np.ndarray


def rasterise_uvs(uvs: np.ndarray, uv_faces: np.ndarray, size: int) -> TexelSamples:
    """Texel centres ``((col + 0.5) / size, (row + 0.5) / size)`` inside each UV triangle."""
    rows, cols, faces, barys = [], [], [], []
    tri = uvs[uv_faces] * size - 0.5  # texel-centre coordinates
    for f, (a, b, c) in enumerate(tri):
        lo = np.floor(np.minimum(np.minimum(a, b), c)).astype(int).clip(0, size - 1)
        hi = np.ceil(np.maximum(np.maximum(a, b), c)).astype(int).clip(0, size - 1)
        uu, vv = np.meshgrid(np.arange(lo[0], hi[0] + 1), np.arange(lo[1], hi[1] + 1))
        q = np.stack([uu.ravel(), vv.ravel()], 1).astype(np.float64)
        m = np.array([b - a, c - a]).T
        det = np.linalg.det(m)
        if abs(det) < 1e-12:
            continue
        l12 = np.linalg.solve(m, (q - a).T).T
        bary = np.column_stack([1 - l12.sum(1), l12])
        inside = (bary >= -1e-9).all(1)
        rows.append(q[inside, 1].astype(int))
        cols.append(q[inside, 0].astype(int))
        faces.append(np.full(inside.sum(), f))
        barys.append(bary[inside])
    return TexelSamples(*(np.concatenate(x) for x in (rows, cols, faces, barys)))


def tangent_frames(
    positions: np.ndarray,
    normals: np.ndarray,
    uvs: np.ndarray,
    faces: np.ndarray,
    samples: TexelSamples,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Surface points and Mitsuba shading frames ``(s, t, n)`` at the texel samples, each
    ``(K, 3)``, for an atlas mesh with per-vertex ``positions, normals (A, 3)``, ``uvs (A, 2)``."""
    corners = faces[samples.face]
    p = np.einsum("kj,kjc->kc", samples.bary, positions[corners])
    n = np.einsum("kj,kjc->kc", samples.bary, normals[corners])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    e1 = positions[corners[:, 1]] - positions[corners[:, 0]]
    e2 = positions[corners[:, 2]] - positions[corners[:, 0]]
    d1 = uvs[corners[:, 1]] - uvs[corners[:, 0]]
    d2 = uvs[corners[:, 2]] - uvs[corners[:, 0]]
    det = d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]
    dp_du = (d2[:, 1:2] * e1 - d1[:, 1:2] * e2) / det[:, None]
    s = dp_du - n * (n * dp_du).sum(1, keepdims=True)
    s /= np.linalg.norm(s, axis=1, keepdims=True)
    return p, s, np.cross(n, s), n


def cast_to_detail(
    origins: np.ndarray, dirs: np.ndarray, vertices: np.ndarray, faces: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Nearest hit of the detailed mesh along ``+dirs`` or ``-dirs`` from ``origins``.

    Returns:
        hit mask ``(K,)``, face index ``(K,)`` and barycentrics ``(K, 3)`` of the hits.
    """
    scene = embree_scene(vertices, faces)
    best = np.full(len(origins), np.inf)
    face = np.full(len(origins), -1)
    bary = np.zeros((len(origins), 3))
    for sign in (1.0, -1.0):
        hits = first_hits(scene, faces, origins, sign * dirs)
        closer = hits.distance < best  # False for misses (distance inf)
        best[closer] = hits.distance[closer]
        face[closer] = hits.face[closer]
        bary[closer] = hits.bary[closer[hits.mask]]
    return face >= 0, face, bary


def dilate(texture: np.ndarray, covered: np.ndarray) -> np.ndarray:
    """Fill texels outside ``covered (T, T)`` with the nearest covered texel's value."""
    _, (ri, ci) = scipy.ndimage.distance_transform_edt(~covered, return_indices=True)
    return texture[ri, ci]


def bake(
    low: LowPolyMesh,
    detail_vertices: np.ndarray,
    detail_faces: np.ndarray,
    size: int,
    colour_fn: AttributeFn | None = None,
    normal_fn: AttributeFn | None = None,
) -> tuple[np.ndarray, np.ndarray | None]:
    """Bake a tangent-space normal map (and a colour map when ``colour_fn`` is given).

    Args:
        low: the atlas mesh (its current welded positions are used).
        detail_vertices, detail_faces: the detailed surface rays are cast against.
        size: texture width = height in texels.
        colour_fn, normal_fn: ``(points (K, 3), face (K,), bary (K, 3)) -> (K, 3)`` colour
            and unit normal of the detailed surface at hits; the default normal interpolates
            the detailed mesh's area-weighted vertex normals.

    Returns:
        normal map ``(size, size, 3)`` in [0, 1] and colour map ``(size, size, 3)`` or None.
    """
    if normal_fn is None:
        detail_n = vertex_normals(detail_vertices, detail_faces)

        def normal_fn(points, face, bary):
            n = np.einsum("kj,kjc->kc", bary, detail_n[detail_faces[face]])
            return n / np.linalg.norm(n, axis=1, keepdims=True)

    positions = low.atlas_positions()
    normals = vertex_normals(low.positions, low.faces)[low.vmap]
    samples = rasterise_uvs(low.uvs, low.uv_faces, size)
    p, s, t, n = tangent_frames(positions, normals, low.uvs, low.uv_faces, samples)
    hit, face, bary = cast_to_detail(p, n, detail_vertices, detail_faces)
    points = np.einsum("kj,kjc->kc", bary[hit], detail_vertices[detail_faces[face[hit]]])
    local = np.tile([0.0, 0.0, 1.0], (len(p), 1))  # misses keep the low-poly normal
    world = normal_fn(points, face[hit], bary[hit])
    local[hit] = np.stack([(world * a[hit]).sum(1) for a in (s, t, n)], 1)
    covered = np.zeros((size, size), dtype=bool)
    covered[samples.rows, samples.cols] = True
    normal_map = np.zeros((size, size, 3))
    normal_map[samples.rows, samples.cols] = (local + 1) / 2
    colour_map = None
    if colour_fn is not None:
        colour = np.full((len(p), 3), 0.5)
        colour[hit] = colour_fn(points, face[hit], bary[hit])
        colour_map = np.zeros((size, size, 3))
        colour_map[samples.rows, samples.cols] = colour
        colour_map = dilate(colour_map, covered)
    return dilate(normal_map, covered), colour_map
