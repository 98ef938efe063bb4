"""Triangle meshes and grid meshes: normals and connectivity every method shares, and
vector arithmetic on components.

Conventions: positions ``(V, 3)`` float in world units, faces ``(F, 3)`` int vertex indices,
counter-clockwise seen from the side the normals point to. A grid mesh is an ``n x n``
array of vertices ``(n, n, 3)`` (a geometry image) flattened row-major (vertex ``(i, j)`` is
``i * n + j``) and triangulated by :func:`grid_faces`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


def vertex_normals(positions: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted unit vertex normals ``(V, 3)`` of a triangle mesh ``(V, 3)``, ``(F, 3)``.

    A vertex that no triangle uses (or only degenerate ones) gets a zero normal.
    """
    p = positions.reshape(-1, 3)
    fn = np.cross(p[faces[:, 1]] - p[faces[:, 0]], p[faces[:, 2]] - p[faces[:, 0]])
    corners = faces.ravel()
    normals = np.stack([np.bincount(corners, np.repeat(fn[:, c], 3), len(p)) for c in range(3)], 1)
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    return normals / np.maximum(length, 1e-20)


def grid_faces(n: int) -> np.ndarray:
    """Triangles of the ``n x n`` grid mesh ``(2 (n-1)^2, 3)``, counter-clockwise when row
    ``i`` is ``v`` and column ``j`` is ``u``."""
    idx = np.arange(n * n).reshape(n, n)
    a, b = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel()
    c, d = idx[1:, :-1].ravel(), idx[1:, 1:].ravel()
    return np.concatenate([np.stack([a, b, d], 1), np.stack([a, d, c], 1)])


def grid_normals(positions: np.ndarray) -> np.ndarray:
    """Unit normals ``(n, n, 3)`` of a grid mesh ``(n, n, 3)``.

    A square corner of the grid has only one or two triangles, and they are nearly
    degenerate where a smooth boundary was pinned to a 90-degree corner; the four corner
    vertices therefore take the normal of their diagonal neighbour.
    """
    n = positions.shape[0]
    normals = vertex_normals(positions.reshape(-1, 3).astype(np.float64), grid_faces(n)).reshape(
        n, n, 3
    )
    for i, j in ((0, 0), (0, -1), (-1, 0), (-1, -1)):
        normals[i, j] = normals[1 if i == 0 else -2, 1 if j == 0 else -2]
    return normals


def dot_components(a: Sequence, b: Sequence):
    """Dot product of two 3-vectors given as their components (three arrays or tensors of
    one shape each), element-wise: what an ONNX graph runs fastest, with no last axis of 3
    (see :mod:`neurender.ndr.prefiltered`)."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
