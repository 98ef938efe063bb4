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
import scipy.sparse
import scipy.sparse.csgraph


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


def float32_rounding(positions: np.ndarray) -> float:
    """The largest rounding of ``positions (V, 3)`` stored as float32 absolute coordinates
    (half the float32 spacing at the farthest coordinate), as a fraction of their bounding
    box's longest side: about 3e-8 for a mesh about the origin, 0.125 for a 2 m scan in
    georeferenced coordinates (y ~ 5.4e6 m, 0.5 m apart in float32); 0 for a single point."""
    side = float(np.ptp(positions.reshape(-1, 3), axis=0).max())
    far = np.float32(np.abs(positions).max())
    return float(np.spacing(far)) / 2 / side if side > 0 else 0.0


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


def winding_flips(positions: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Which triangles to flip (``(a, b, c)`` to ``(c, b, a)``) so that every surface winds
    one way: a closed one with its normals outward, an open one as most of its triangles.

    The surfaces are the sheets of triangles joined across manifold edges (edges of exactly
    two triangles) once vertices at one position count as one (files split them at UV
    seams). A two-sided sheet (not a Moebius strip) is made consistent: a closed one (every
    edge manifold) then has a positive signed volume, unless its volume is negative and it
    lies inside another closed sheet (a cavity, whose normals rightly face into it); an
    open one, which has no inside, keeps the winding of the majority of its triangles.
    Triangles with two corners at one position, one-sided sheets and closed sheets of
    negligible volume are left as they are; a sheet ends at a non-manifold edge (the two
    copies of a double-sided leaf stay two sheets, each as wound).

    Args:
        positions: ``(V, 3)`` float vertex positions.
        faces: ``(F, 3)`` int triangles.

    Returns:
        ``flip`` ``(F,)`` bool, the triangles to flip, and ``closed`` ``(F,)`` bool, the
        triangles on a two-sided closed sheet.
    """
    points, weld = _same_positions(np.asarray(positions, np.float64).reshape(-1, 3))
    welded = weld[np.asarray(faces, np.int64)]
    flip, closed = np.zeros(len(welded), bool), np.zeros(len(welded), bool)
    valid = np.flatnonzero(
        (welded[:, 0] != welded[:, 1])
        & (welded[:, 1] != welded[:, 2])
        & (welded[:, 2] != welded[:, 0])
    )
    n, tris = len(valid), welded[valid]
    if n == 0:
        return flip, closed
    half = tris[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    key = half.min(1) * len(points) + half.max(1)
    _, edge, count = np.unique(key, return_inverse=True, return_counts=True)
    order = np.argsort(edge, kind="stable")
    starts = np.flatnonzero(np.r_[True, np.diff(edge[order]) != 0])
    pairs = starts[count == 2]
    first, second = order[pairs], order[pairs + 1]
    f, g = first // 3, second // 3
    # Two triangles agree when they run along their shared edge in opposite directions.
    disagree = (half[first, 0] < half[first, 1]) == (half[second, 0] < half[second, 1])
    sheets, sheet = scipy.sparse.csgraph.connected_components(
        scipy.sparse.coo_matrix((np.ones(len(f)), (f, g)), shape=(n, n)), directed=False
    )
    # Every triangle twice, as wound (k) and flipped (k + n): a two-sided sheet is two
    # components of this graph, a one-sided one joins a triangle to its own flip.
    rows = np.r_[f, f + n]
    cols = np.r_[np.where(disagree, g + n, g), np.where(disagree, g, g + n)]
    _, side = scipy.sparse.csgraph.connected_components(
        scipy.sparse.coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(2 * n, 2 * n)),
        directed=False,
    )
    two_sided = np.ones(sheets, bool)
    np.logical_and.at(two_sided, sheet, side[:n] != side[n:])
    root = np.full(sheets, n)
    np.minimum.at(root, sheet, np.arange(n))
    against_root = side[:n] != side[root[sheet]]
    is_closed = two_sided.copy()
    np.logical_and.at(is_closed, sheet, (count[edge] == 2).reshape(-1, 3).all(1))
    # Signed volumes and areas of the sheets wound as their first triangle.
    p = points[np.where(against_root[:, None], tris[:, ::-1], tris)]
    volume = np.bincount(sheet, np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])), sheets)
    area = np.bincount(
        sheet, np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1), sheets
    )
    # A closed surface of area A holds at most A^1.5 / (6 sqrt(pi)); 6 V and 2 A are summed.
    inside_out = is_closed & (volume < -1e-6 * (area / 2) ** 1.5)
    if inside_out.any():
        members = np.split(np.argsort(sheet, kind="stable"), np.cumsum(np.bincount(sheet))[:-1])
        low, high = np.full((sheets, 3), np.inf), np.full((sheets, 3), -np.inf)
        np.minimum.at(low, sheet, p.min(1))
        np.maximum.at(high, sheet, p.max(1))
        for s in np.flatnonzero(inside_out):
            # Only a closed sheet whose box holds this one's can enclose it.
            around = is_closed & (low <= low[s]).all(1) & (high >= high[s]).all(1)
            around[s] = False
            inside_out[s] = not _enclosed(points, tris, members, s, np.flatnonzero(around))
    minority = np.bincount(sheet, against_root, sheets) > np.bincount(sheet, None, sheets) / 2
    reverse = np.where(is_closed, inside_out, minority)
    flip[valid] = two_sided[sheet] & (against_root != reverse[sheet])
    closed[valid] = is_closed[sheet]
    return flip, closed


def _same_positions(positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The distinct positions ``(P, 3)`` of ``positions (V, 3)`` and the index ``(V,)`` of
    each vertex's among them."""
    order = np.lexsort(positions.T[::-1])
    new = np.r_[True, (positions[order[1:]] != positions[order[:-1]]).any(1)]
    index = np.empty(len(positions), np.int64)
    index[order] = np.cumsum(new) - 1
    return positions[order[new]], index


def _enclosed(points: np.ndarray, tris: np.ndarray, members: list, s: int, others) -> bool:
    """Whether sheet ``s`` (triangles ``tris[members[s]]``) lies inside an odd number of
    the closed sheets ``others``: the generalised winding number, whatever their winding,
    at the centroids of up to 8 of its triangles, above one half."""
    import igl  # libigl only where a surface may be inside out

    own = tris[members[s]]
    query = np.ascontiguousarray(points[own[:: max(1, len(own) // 8)][:8]].mean(1))
    inside = sum(
        np.abs(igl.winding_number(points, tris[members[t]], query)).mean() > 0.5 for t in others
    )
    return inside % 2 == 1
