"""Geometry images (Gu et al. 2002) of disk-topology meshes via a harmonic map to the unit square.

Conventions: the parametric domain is ``[0, 1]^2`` with ``uv = (u, v)``; grid vertex ``(i, j)``
of an ``n x n`` geometry image sits at ``u = j / (n - 1)``, ``v = i / (n - 1)``, so row ``i``
is an image row and column ``j`` an image column. Grid vertices are flattened row-major
(index ``i * n + j``). Positions are in the source mesh's world units.
"""

from __future__ import annotations

import dataclasses

import igl
import numpy as np
import scipy.sparse
import scipy.sparse.linalg

from neurender.geometry import grid_faces

# Corners of the square, counter-clockwise, matching a counter-clockwise boundary loop.
_SQUARE_CORNERS = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])


@dataclasses.dataclass
class GeometryImage:
    """Resampling of a source mesh on an ``n x n`` grid of its square parametrisation.

    Attributes:
        uv: ``(V, 2)`` parametric coordinates of the source vertices.
        face: ``(n*n,)`` int source triangle containing each grid point.
        bary: ``(n*n, 3)`` barycentric weights of each grid point in that triangle.
        n: grid side.
        method: ``"cotangent"`` or ``"uniform"`` (Tutte) weights.
        flipped: number of flipped (non-positive area) triangles of the map.
    """

    uv: np.ndarray
    face: np.ndarray
    bary: np.ndarray
    n: int
    method: str
    flipped: int

    def resample(self, faces: np.ndarray, values: np.ndarray) -> np.ndarray:
        """Interpolate per-source-vertex ``values`` ``(V, ...)`` onto the grid ``(n, n, ...)``."""
        corners = values[faces[self.face]]  # (n*n, 3, ...)
        w = self.bary.reshape(self.bary.shape + (1,) * (values.ndim - 1))
        out = (corners * w).sum(axis=1)
        return out.reshape((self.n, self.n) + values.shape[1:])


def boundary_square(vertices: np.ndarray, loop: np.ndarray) -> np.ndarray:
    """Map a boundary loop to the unit square's perimeter by arc length, four corners pinned.

    Corners are the loop vertices nearest to arc-length fractions 0, 1/4, 1/2, 3/4; between
    two corners the vertices are spread by arc length along that side.

    Args:
        vertices: ``(V, 3)`` positions.
        loop: ``(L,)`` boundary vertex indices in order (L >= 4).

    Returns:
        ``(L, 2)`` points on the perimeter, in loop order.
    """
    if len(loop) < 4:
        raise ValueError(f"boundary loop has {len(loop)} vertices; a square needs at least 4")
    seg = np.linalg.norm(vertices[np.roll(loop, -1)] - vertices[loop], axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])  # arc length at each loop vertex, then the total
    total = s[-1]
    corners = [int(np.argmin(np.abs(s[:-1] - k * total / 4))) for k in range(4)]
    if len(set(corners)) < 4:
        raise ValueError("boundary loop too short to pin four distinct corners")
    out = np.zeros((len(loop), 2))
    for k in range(4):
        a, b = corners[k], corners[(k + 1) % 4]
        idx = np.arange(a, b + 1) if b > a else np.arange(a, b + 1 + len(loop))
        arc = s[idx] if b > a else np.concatenate([s[a:-1], s[: b + 1] + total])
        t = (arc - arc[0]) / (arc[-1] - arc[0])
        p0, p1 = _SQUARE_CORNERS[k], _SQUARE_CORNERS[(k + 1) % 4]
        out[idx % len(loop)] = p0 + t[:, None] * (p1 - p0)
    return out


def signed_areas(uv: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Signed area of each triangle in the plane ``(F,)`` (positive = counter-clockwise)."""
    a, b, c = uv[faces[:, 0]], uv[faces[:, 1]], uv[faces[:, 2]]
    return 0.5 * (
        (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    )


def _tutte(faces: np.ndarray, n_vertices: int, b: np.ndarray, bc: np.ndarray) -> np.ndarray:
    """Uniform-weight (Tutte) embedding: always bijective for a convex boundary."""
    edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    edges = np.unique(np.sort(edges, axis=1), axis=0)
    i, j = np.concatenate([edges[:, 0], edges[:, 1]]), np.concatenate([edges[:, 1], edges[:, 0]])
    adj = scipy.sparse.csr_matrix((np.ones(len(i)), (i, j)), shape=(n_vertices, n_vertices))
    lap = scipy.sparse.diags(np.asarray(adj.sum(axis=1)).ravel()) - adj
    interior = np.setdiff1d(np.arange(n_vertices), b)
    uv = np.zeros((n_vertices, 2))
    uv[b] = bc
    rhs = -lap[interior][:, b] @ bc
    solve = scipy.sparse.linalg.factorized(lap[interior][:, interior].tocsc())
    uv[interior] = np.stack([solve(rhs[:, k]) for k in range(2)], axis=1)
    return uv


def harmonic_square_map(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, str, int]:
    """Harmonic (cotangent) map of a disk-topology mesh onto the unit square.

    Falls back to uniform (Tutte) weights when cotangent weights flip a triangle (obtuse
    triangles make cotangent weights negative).

    Returns:
        ``uv`` ``(V, 2)``, the weights used, and the number of flipped triangles left.
    """
    loop = np.asarray(igl.boundary_loop(faces), dtype=np.int64)
    # Start at the lower-left extreme (min x + y) so a face-like mesh facing +z gets its
    # corners on the diagonals and lands upright in the image.
    loop = np.roll(loop, -int(np.argmin(vertices[loop, 0] + vertices[loop, 1])))
    bc = boundary_square(vertices, loop)
    # Orient the loop like the square (counter-clockwise w.r.t. the faces); a reversed loop
    # would flip every triangle.
    uv = igl.harmonic(vertices, faces, loop, bc, 1)
    if signed_areas(uv, faces).sum() < 0:
        loop = np.roll(loop[::-1], 1)  # same start vertex, other direction
        bc = boundary_square(vertices, loop)
        uv = igl.harmonic(vertices, faces, loop, bc, 1)
    flipped = int((signed_areas(uv, faces) <= 0).sum())
    if flipped == 0:
        return uv, "cotangent", 0
    uv = _tutte(faces, len(vertices), loop, bc)
    return uv, "uniform", int((signed_areas(uv, faces) <= 0).sum())


def grid_uv(n: int) -> np.ndarray:
    """Parametric coordinates of the ``n x n`` grid, ``(n*n, 2)`` row-major (u = column)."""
    t = np.linspace(0.0, 1.0, n)
    v, u = np.meshgrid(t, t, indexing="ij")
    return np.stack([u.ravel(), v.ravel()], axis=1)


def build_geometry_image(vertices: np.ndarray, faces: np.ndarray, n: int) -> GeometryImage:
    """Parametrise a disk-topology mesh and locate every grid point in it.

    Args:
        vertices: ``(V, 3)`` float positions.
        faces: ``(F, 3)`` int triangles.
        n: grid side.
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    uv, method, flipped = harmonic_square_map(vertices, faces)
    uv3 = np.column_stack([uv, np.zeros(len(uv))])  # igl's AABB wants 3-D points
    tree = igl.AABB()
    tree.init(uv3, faces)
    query = np.column_stack([grid_uv(n), np.zeros(n * n)])
    _, face, closest = tree.squared_distance(uv3, faces, query)
    face = np.asarray(face, dtype=np.int64).ravel()
    tri = uv3[faces[face]]
    bary = igl.barycentric_coordinates(closest, tri[:, 0], tri[:, 1], tri[:, 2])
    bary = np.clip(bary, 0.0, None)
    bary /= bary.sum(axis=1, keepdims=True)
    return GeometryImage(uv=uv, face=face, bary=bary, n=n, method=method, flipped=flipped)


def reconstruction_error(
    source_vertices: np.ndarray, source_faces: np.ndarray, grid_positions: np.ndarray
) -> dict[str, float]:
    """Symmetric surface distance between the source mesh and its grid mesh S_R.

    Distances are point-to-surface in both directions (source vertices to S_R, grid
    vertices to the source), relative to the source's bounding-box diagonal.

    Returns:
        ``{"mean": ..., "max": ...}`` relative distances.
    """
    n = grid_positions.shape[0]
    grid = grid_positions.reshape(-1, 3).astype(np.float64)
    src = np.asarray(source_vertices, dtype=np.float64)
    d1, _, _ = igl.point_mesh_squared_distance(src, grid, grid_faces(n))
    d2, _, _ = igl.point_mesh_squared_distance(grid, src, np.asarray(source_faces, dtype=np.int64))
    d = np.sqrt(np.concatenate([d1, d2]))
    diag = float(np.linalg.norm(src.max(0) - src.min(0)))
    return {"mean": float(d.mean() / diag), "max": float(d.max() / diag)}
