"""Geometry images (Gu et al. 2002) of disk-topology meshes via a harmonic map to the unit square.

Conventions: the parametric domain is ``[0, 1]^2`` with ``uv = (u, v)``; grid vertex ``(i, j)``
of an ``n x n`` geometry image sits at ``u = j / (n - 1)``, ``v = i / (n - 1)``, so row ``i``
is an image row and column ``j`` an image column. Grid vertices are flattened row-major
(index ``i * n + j``). Positions are in the source mesh's world units.

The map is harmonic (cotangent weights) where that is bijective, else uniform (Tutte)
weights, which Floater's theorem makes bijective for a convex boundary unless an interior
edge joins two vertices on one side of the square: the triangles between such an edge
and that side (a boundary "ear" of a third-party mesh, a chord along a cut) collapse onto
the side. When the map flips a triangle, :func:`build_geometry_image` splits every such
edge at its midpoint (the new vertex is interior) and maps again, so a disk always maps
without flipped triangles; the grid's lookup is then expressed in the input's triangles.
Map quality is reported as Sander et al.'s (2001) L2 and max stretch, normalised so that 1
is isometric. Meshes that are not disks are made disks first (:func:`parametrise`).
"""

from __future__ import annotations

import dataclasses

import igl
import numpy as np
import scipy.sparse
import scipy.sparse.linalg

from neurender.geometry import grid_faces
from neurender.prt.disk import DiskMesh, to_disk

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
        split_edges: interior edges split at their midpoint before mapping (their two
            ends on one side of the square); their new vertices follow the rows of ``uv``
            that belong to the source vertices.
        stretch_l2, stretch_max: Sander et al.'s normalised L2 and max stretch of the map.
        uv_faces: ``(F', 3)`` triangles of ``uv`` (the input's, split where needed).
    """

    uv: np.ndarray
    face: np.ndarray
    bary: np.ndarray
    n: int
    method: str
    flipped: int
    split_edges: int = 0
    stretch_l2: float = float("nan")
    stretch_max: float = float("nan")
    uv_faces: np.ndarray | None = None

    def resample(self, faces: np.ndarray, values: np.ndarray) -> np.ndarray:
        """Interpolate per-source-vertex ``values`` ``(V, ...)`` onto the grid ``(n, n, ...)``."""
        return resample(self.face, self.bary, self.n, faces, values)


def resample(
    face: np.ndarray, bary: np.ndarray, n: int, faces: np.ndarray, values: np.ndarray
) -> np.ndarray:
    """Per-vertex ``values`` ``(V, ...)`` of a mesh with triangles ``faces`` on the
    ``n x n`` grid ``(n, n, ...)``, grid point ``k`` at barycentric coordinates ``bary[k]``
    in triangle ``face[k]`` (a :class:`GeometryImage`'s lookup)."""
    corners = values[faces[face]]  # (n*n, 3, ...)
    w = bary.reshape(bary.shape + (1,) * (values.ndim - 1))
    out = (corners * w).sum(axis=1)
    return out.reshape((n, n) + values.shape[1:])


def perimeter_points(
    vertices: np.ndarray,
    loop: np.ndarray,
    uniform_share: float = 0.0,
    corners: list[int] | None = None,
) -> np.ndarray:
    """Points on the unit square's perimeter for a given boundary loop, by arc length, four
    corners pinned.

    Corners are the loop vertices nearest to arc-length fractions 0, 1/4, 1/2, 3/4; between
    two corners the vertices are spread by arc length along that side.

    Args:
        vertices: ``(V, 3)`` positions.
        loop: ``(L,)`` boundary vertex indices in order (L >= 4).
        uniform_share: weight of uniform spacing blended into the arc length, so that
            boundary edges of zero length still get distinct points.
        corners: four increasing positions in ``loop`` to pin to the corners instead
            (the first must be 0).

    Returns:
        ``(L, 2)`` points on the perimeter, in loop order.
    """
    if len(loop) < 4:
        raise ValueError(
            f"the boundary loop has {len(loop)} vertices; expected at least 4, one per corner "
            "of the square it is pinned to (a single triangle has 3; a quad of two has 4)"
        )
    seg = np.linalg.norm(vertices[np.roll(loop, -1)] - vertices[loop], axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])  # arc length at each loop vertex, then the total
    if uniform_share:
        s = (1 - uniform_share) * s / s[-1] + uniform_share * np.arange(len(s)) / len(loop)
    total = s[-1]
    if corners is None:
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


def pinned_boundary(
    vertices: np.ndarray,
    faces: np.ndarray,
    uniform_share: float = 0.0,
    anchors: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Where a disk's boundary is pinned on the square: its boundary loop ``(L,)``, found,
    started and oriented counter-clockwise like the square, and the loop's points on the
    perimeter ``(L, 2)`` (:func:`perimeter_points`).

    ``anchors`` ``(V,)`` marks the boundary vertices where the cut of a closed surface
    branches or ends (:class:`neurender.prt.disk.DiskMesh`): the loop then starts at one
    and, when there are at least four, every corner is the one nearest to its quarter of
    the arc length, so a torus cut along a meridian and a longitude unrolls onto the
    square as the rectangle it is.
    """
    loop = np.asarray(igl.boundary_loop(faces), dtype=np.int64)
    # Start at the lower-left extreme (min x + y) so a face-like mesh facing +z gets its
    # corners on the diagonals and lands upright in the image.
    marked = np.zeros(len(loop), bool) if anchors is None else anchors[loop]
    candidates = np.nonzero(marked)[0] if marked.any() else np.arange(len(loop))
    key = vertices[loop[candidates], 0] + vertices[loop[candidates], 1]
    loop = np.roll(loop, -int(candidates[np.argmin(key)]))
    # The interior lies left of a boundary edge in its triangle's order, as it does left of
    # the square's counter-clockwise perimeter; a loop the other way would flip every triangle.
    directed = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    if not ((directed[:, 0] == loop[0]) & (directed[:, 1] == loop[1])).any():
        loop = np.roll(loop[::-1], 1)  # same start vertex, other direction
    corners = None
    if marked.sum() >= 4:
        corners = _anchored_corners(vertices, loop, np.nonzero(anchors[loop])[0])
    return loop, perimeter_points(vertices, loop, uniform_share, corners)


def _anchored_corners(
    vertices: np.ndarray, loop: np.ndarray, marked: np.ndarray
) -> list[int] | None:
    """Positions in ``loop`` of the marked vertices nearest to the quarters of its arc
    length (``marked`` holds 0, the start); None when two quarters pick the same one."""
    seg = np.linalg.norm(vertices[np.roll(loop, -1)] - vertices[loop], axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    corners = [0] + [int(marked[np.argmin(np.abs(s[marked] - k * s[-1] / 4))]) for k in (1, 2, 3)]
    return corners if all(np.diff(corners) > 0) else None


def count_flipped(uv: np.ndarray, faces: np.ndarray) -> int:
    """Triangles of non-positive (or undefined) area in the plane."""
    return int((~(signed_areas(uv, faces) > 0)).sum())


def map_to_square(
    vertices: np.ndarray, faces: np.ndarray, loop: np.ndarray, bc: np.ndarray
) -> tuple[np.ndarray, str, int]:
    """Harmonic (cotangent) map with the boundary ``loop`` pinned at ``bc``; uniform
    (Tutte) weights when that flips a triangle (obtuse triangles make cotangent weights
    negative, degenerate ones undefined).

    Returns:
        ``uv`` ``(V, 2)``, the weights used, and the number of flipped triangles left.
    """
    with np.errstate(all="ignore"):
        uv = igl.harmonic(vertices, faces, loop, bc, 1)
    if np.isfinite(uv).all() and count_flipped(uv, faces) == 0:
        return uv, "cotangent", 0
    uv = _tutte(faces, len(vertices), loop, bc)
    return uv, "uniform", count_flipped(uv, faces)


def harmonic_square_map(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, str, int]:
    """Harmonic map of a disk-topology mesh onto the unit square (:func:`map_to_square`),
    boundary by arc length (:func:`pinned_boundary`).

    Returns:
        ``uv`` ``(V, 2)``, the weights used, and the number of flipped triangles left.
    """
    loop, bc = pinned_boundary(vertices, faces)
    return map_to_square(vertices, faces, loop, bc)


def same_side_edges(faces: np.ndarray, loop: np.ndarray, bc: np.ndarray) -> np.ndarray:
    """Interior edges ``(E, 2)`` whose two ends lie on one side of the square (a corner
    lies on both of its sides): Floater's condition for a bijective Tutte map fails there."""
    bits = np.zeros(int(faces.max()) + 1, np.int64)
    bits[loop] = (
        (bc[:, 1] == 0) * 1 + (bc[:, 0] == 1) * 2 + (bc[:, 1] == 1) * 4 + (bc[:, 0] == 0) * 8
    )
    edges = np.unique(np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1), axis=0)
    boundary = np.sort(np.stack([loop, np.roll(loop, -1)], 1), axis=1)
    base = len(bits)
    on_boundary = np.isin(edges @ [base, 1], boundary @ [base, 1])
    return edges[((bits[edges[:, 0]] & bits[edges[:, 1]]) != 0) & ~on_boundary]


def split_edges(
    vertices: np.ndarray, faces: np.ndarray, edges: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Split each edge at its midpoint, and the (one or two) triangles on it in two.

    Returns:
        vertices with the midpoints appended, the new faces (same winding), each new
        triangle's source triangle ``(F',)`` and its corners' barycentric coordinates in
        that triangle ``(F', 3, 3)``.
    """
    vertices = list(np.asarray(vertices, dtype=np.float64))
    faces = [list(f) for f in np.asarray(faces, dtype=np.int64)]
    parent = list(range(len(faces)))
    corners = [np.eye(3) for _ in faces]
    targets = {tuple(sorted(e)) for e in np.asarray(edges).tolist()}
    owners = {e: [] for e in targets}  # the triangles on each edge still to split
    for k, f in enumerate(faces):
        for i in range(3):
            e = tuple(sorted((f[i], f[(i + 1) % 3])))
            if e in owners:
                owners[e].append(k)
    for a, b in sorted(targets):
        m = len(vertices)
        vertices.append(0.5 * (vertices[a] + vertices[b]))
        for k in owners.pop((a, b)):
            f, w = faces[k], corners[k]
            i = next(i for i in range(3) if {f[i], f[(i + 1) % 3]} == {a, b})
            x, y, z = f[i], f[(i + 1) % 3], f[(i + 2) % 3]
            wm = 0.5 * (w[i] + w[(i + 1) % 3])
            # (x, y, z) -> (x, m, z) in place and (m, y, z) appended; edge (y, z) moves.
            faces[k], corners[k] = [x, m, z], np.stack([w[i], wm, w[(i + 2) % 3]])
            faces.append([m, y, z])
            corners.append(np.stack([wm, w[(i + 1) % 3], w[(i + 2) % 3]]))
            parent.append(parent[k])
            moved = tuple(sorted((y, z)))
            if moved in owners:
                owners[moved] = [len(faces) - 1 if o == k else o for o in owners[moved]]
    return (
        np.array(vertices),
        np.array(faces, dtype=np.int64),
        np.array(parent, dtype=np.int64),
        np.array(corners),
    )


def stretch(vertices: np.ndarray, faces: np.ndarray, uv: np.ndarray) -> dict[str, float]:
    """Sander et al.'s (2001) stretch of the map from the plane ``uv`` to the surface.

    Per triangle, with ``a, b, c`` the entries of the metric tensor of the Jacobian
    ``(dS/du, dS/dv)``: L2 stretch ``sqrt((a + c) / 2)`` and max stretch ``Gamma`` (the
    larger singular value). Returns the area-weighted L2 norm over the surface and the
    largest ``Gamma``, both times ``sqrt(planar area / surface area)`` so that 1 is
    isometric (up to scale) and larger is worse; flipped triangles are left out.
    """
    q = np.asarray(vertices, dtype=np.float64)[faces]
    p = np.asarray(uv, dtype=np.float64)[faces]
    s, t = p[..., 0], p[..., 1]
    area2 = signed_areas(uv, faces)
    area3 = 0.5 * np.linalg.norm(np.cross(q[:, 1] - q[:, 0], q[:, 2] - q[:, 0]), axis=1)
    ok = area2 > 0
    q, s, t, a2 = q[ok], s[ok], t[ok], area2[ok][:, None]
    ss = (
        q[:, 0] * (t[:, 1:2] - t[:, 2:3])
        + q[:, 1] * (t[:, 2:3] - t[:, 0:1])
        + q[:, 2] * (t[:, 0:1] - t[:, 1:2])
    ) / (2 * a2)
    st = (
        q[:, 0] * (s[:, 2:3] - s[:, 1:2])
        + q[:, 1] * (s[:, 0:1] - s[:, 2:3])
        + q[:, 2] * (s[:, 1:2] - s[:, 0:1])
    ) / (2 * a2)
    a, b, c = (ss * ss).sum(1), (ss * st).sum(1), (st * st).sum(1)
    l2 = np.sqrt((a + c) / 2)
    gamma = np.sqrt(((a + c) + np.sqrt((a - c) ** 2 + 4 * b * b)) / 2)
    scale = np.sqrt(area2[ok].sum() / area3[ok].sum())
    return {
        "l2": float(np.sqrt((l2**2 * area3[ok]).sum() / area3[ok].sum()) * scale),
        "max": float(gamma.max() * scale),
    }


def grid_uv(n: int) -> np.ndarray:
    """Parametric coordinates of the ``n x n`` grid, ``(n*n, 2)`` row-major (u = column)."""
    t = np.linspace(0.0, 1.0, n)
    v, u = np.meshgrid(t, t, indexing="ij")
    return np.stack([u.ravel(), v.ravel()], axis=1)


def build_geometry_image(
    vertices: np.ndarray, faces: np.ndarray, n: int, anchors: np.ndarray | None = None
) -> GeometryImage:
    """Parametrise a disk-topology mesh and locate every grid point in it.

    Args:
        vertices: ``(V, 3)`` float positions.
        faces: ``(F, 3)`` int triangles.
        n: grid side.
        anchors: ``(V,)`` bool, boundary vertices preferred as corners
            (:func:`pinned_boundary`).
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    loop, bc = pinned_boundary(vertices, faces, anchors=anchors)
    uv, method, flipped = map_to_square(vertices, faces, loop, bc)
    mapped_vertices, mapped_faces = vertices, faces
    parent, corners, split = np.arange(len(faces)), None, np.zeros((0, 2), np.int64)
    if flipped:
        # Boundary edges of zero length (repeated vertices) would share a point of the square.
        seg = np.linalg.norm(vertices[np.roll(loop, -1)] - vertices[loop], axis=1)
        if (seg <= 1e-12 * seg.sum()).any():
            loop, bc = pinned_boundary(vertices, faces, 0.05, anchors)
        split = same_side_edges(faces, loop, bc)
        mapped_vertices, mapped_faces, parent, corners = split_edges(vertices, faces, split)
        uv, method, flipped = map_to_square(mapped_vertices, mapped_faces, loop, bc)
    uv3 = np.column_stack([uv, np.zeros(len(uv))])  # igl's AABB wants 3-D points
    tree = igl.AABB()
    tree.init(uv3, mapped_faces)
    query = np.column_stack([grid_uv(n), np.zeros(n * n)])
    _, face, closest = tree.squared_distance(uv3, mapped_faces, query)
    face = np.asarray(face, dtype=np.int64).ravel()
    tri = uv3[mapped_faces[face]]
    bary = igl.barycentric_coordinates(closest, tri[:, 0], tri[:, 1], tri[:, 2])
    bary = np.clip(bary, 0.0, None)
    bary /= bary.sum(axis=1, keepdims=True)
    if corners is not None:  # back to the triangles of the input mesh
        face, bary = parent[face], np.einsum("pk,pkc->pc", bary, corners[face])
    quality = stretch(mapped_vertices, mapped_faces, uv)
    return GeometryImage(
        uv=uv,
        face=face,
        bary=bary,
        n=n,
        method=method,
        flipped=flipped,
        split_edges=len(split),
        stretch_l2=quality["l2"],
        stretch_max=quality["max"],
        uv_faces=mapped_faces,
    )


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


def parametrise(
    vertices: np.ndarray, faces: np.ndarray, n: int, name: str
) -> tuple[GeometryImage, DiskMesh]:
    """Geometry image of any single connected surface: made a disk
    (:func:`neurender.prt.disk.to_disk`), mapped (:func:`build_geometry_image`), and its
    lookup expressed in the input's triangles, so :meth:`GeometryImage.resample` with
    ``faces`` resamples any per-vertex quantity of the input mesh (every frame of an
    animation). ``uv`` holds the disk's vertices (seam vertices twice).

    Raises:
        ValueError: naming ``name`` (the mesh's file or object), for a surface
            :func:`neurender.prt.disk.to_disk` refuses or a disk too small to map (a
            boundary loop of fewer than 4 vertices: a single triangle).
    """
    disk = to_disk(vertices, faces, name)
    try:
        gim = build_geometry_image(disk.vertices, disk.faces, n, disk.anchors)
    except ValueError as err:  # the map's own messages do not know the mesh's file
        raise ValueError(f"mesh {name}: {err}") from err
    gim.face, gim.bary = disk.lift(gim.face, gim.bary)
    return gim, disk
