"""Any single connected surface made a disk the square map accepts (Gu et al. 2002).

Meshes from other tools arrive with split vertices, doubled or collapsed triangles,
mixed winding, a closed surface or handles. :func:`to_disk` repairs what it can, in
order, and counts every change:

1. weld: vertices closer than :data:`WELD_TOLERANCE` times the bounding-box diagonal are
   merged (exporters split vertices at UV and normal seams; STL stores every triangle's own
   corners); triangles left with two equal corners and repeated triangles are dropped.
   When welding glues a surface to itself into something steps 2-3 refuse (a parametric
   surface that repeats the vertices of its seam or pole), the mesh is kept as it came;
2. check: one edge-connected surface, edge- and vertex-manifold, orientable; anything
   else raises ``ValueError`` naming the mesh and the counts;
3. orient: consistent winding; a closed surface's normals outward (positive volume), an
   open surface keeps its majority's winding (its front);
4. cut: a surface with boundary and handles, or with several boundary loops, along
   libigl's ``cut_to_disk`` (the triangle deletion of Gu et al.'s geometry images); a
   closed surface with handles along its shortest system of loops (greedy homotopy
   generators, Erickson and Whittlesey 2005: a shortest-path tree and a dual cotree,
   each left-over edge closing one loop), which maps a torus with a stretch of 1.5-2
   where ``cut_to_disk``'s cut, whose paths can run side by side, gave up to several
   hundred; a closed genus-0 surface (which ``cut_to_disk`` leaves alone) along the
   shortest edge path between its two extremes on the longest principal axis.
   ``cut_mesh`` then duplicates the vertices on the seam.

Provenance: every triangle of the result remembers its source triangle ``parent`` and
the barycentric coordinates of its three corners in it (``corners``, ``(F, 3, 3)``;
identity rows unless a corner order changed). A point with barycentric coordinates ``b``
in triangle ``k`` is the point ``b @ corners[k]`` of source triangle ``parent[k]``, so any
per-vertex quantity of the source mesh (every frame of an animation) resamples through
the same lookup (:meth:`DiskMesh.lift`).
"""

from __future__ import annotations

import dataclasses

import igl
import numpy as np
import scipy.sparse
import scipy.sparse.csgraph
import scipy.spatial

#: Vertices closer than this fraction of the bounding-box diagonal are one vertex.
WELD_TOLERANCE = 1e-6


@dataclasses.dataclass
class DiskMesh:
    """A disk-topology mesh made from a source mesh, with provenance.

    Attributes:
        vertices: ``(V, 3)`` float64 positions (copies of source vertices).
        faces: ``(F, 3)`` int64 triangles, counter-clockwise seen from the front.
        parent: ``(F,)`` source triangle of each triangle.
        corners: ``(F, 3, 3)`` barycentric coordinates of each corner in its parent.
        vertex_source: ``(V,)`` source vertex each vertex copies.
        anchors: ``(V,)`` bool, copies of the vertices where the cut branches or ends
            (valence other than 2 in the graph of seam and boundary edges), the corners
            the square map prefers.
        changes: counts of what was changed (``welded_vertices``, ``dropped_faces``,
            ``reoriented_faces``, ``seam_edges``), the topology found (``boundary_loops``,
            ``genus``) and ``seam_length`` relative to the bounding-box diagonal.
    """

    vertices: np.ndarray
    faces: np.ndarray
    parent: np.ndarray
    corners: np.ndarray
    vertex_source: np.ndarray
    anchors: np.ndarray
    changes: dict[str, float]

    def lift(self, face: np.ndarray, bary: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Source triangles ``(P,)`` and barycentric coordinates ``(P, 3)`` of points given
        by triangles ``face`` ``(P,)`` of this mesh and coordinates ``bary`` ``(P, 3)``."""
        return self.parent[face], np.einsum("pk,pkc->pc", bary, self.corners[face])


def edges_of(faces: np.ndarray) -> np.ndarray:
    """Directed edges ``(3 F, 2)``: ``(f0, f1), (f1, f2), (f2, f0)`` of every triangle."""
    return faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)


def bbox_diagonal(vertices: np.ndarray) -> float:
    return float(np.linalg.norm(vertices.max(0) - vertices.min(0)))


def weld(
    vertices: np.ndarray, faces: np.ndarray, tolerance: float = WELD_TOLERANCE
) -> tuple[np.ndarray, np.ndarray, int]:
    """Merge vertices closer than ``tolerance`` x the bounding-box diagonal (into the
    lowest index), then drop collapsed and repeated triangles.

    Returns:
        the welded faces of the kept triangles, the indices of the kept triangles and the
        number of vertices merged into another one.
    """
    used = np.unique(faces)
    tree = scipy.spatial.cKDTree(vertices[used])
    pairs = tree.query_pairs(tolerance * bbox_diagonal(vertices[used]), output_type="ndarray")
    rep = np.arange(len(vertices))
    if len(pairs):
        graph = scipy.sparse.coo_matrix(
            (np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(used), len(used))
        )
        _, labels = scipy.sparse.csgraph.connected_components(graph, directed=False)
        first = np.full(labels.max() + 1, len(used))
        np.minimum.at(first, labels, np.arange(len(used)))
        rep[used] = used[first[labels]]
    welded = rep[faces]
    collapsed = (
        (welded[:, 0] == welded[:, 1])
        | (welded[:, 1] == welded[:, 2])
        | (welded[:, 2] == welded[:, 0])
    )
    _, first_copy = np.unique(np.sort(welded, axis=1), axis=0, return_index=True)
    keep = np.zeros(len(faces), bool)
    keep[first_copy] = True
    keep &= ~collapsed
    kept = np.nonzero(keep)[0]
    return welded[kept], kept, int((rep[used] != used).sum())


def check_surface(faces: np.ndarray, name: str) -> None:
    """Raise ``ValueError`` naming ``name`` unless the triangles form one edge-connected,
    edge- and vertex-manifold surface."""
    _, counts = np.unique(np.sort(edges_of(faces), axis=1), axis=0, return_counts=True)
    adjacency = _face_adjacency(faces)
    n_comp, labels = scipy.sparse.csgraph.connected_components(adjacency, directed=False)
    if n_comp != 1:
        sizes = np.sort(np.bincount(labels))[::-1]
        shown = ", ".join(str(s) for s in sizes[:5]) + (", ..." if n_comp > 5 else "")
        raise ValueError(
            f"mesh {name}: {n_comp} connected components ({shown} triangles); a geometry "
            "image needs one connected surface (export the object as one mesh, or remove "
            "the loose parts)"
        )
    non_manifold = int((counts > 2).sum())
    if non_manifold:
        raise ValueError(
            f"mesh {name}: {non_manifold} edges are shared by more than two triangles; a "
            "geometry image needs a manifold surface"
        )
    used = np.unique(faces)
    pinched = int((~igl.is_vertex_manifold(faces)[used]).sum())
    if pinched:
        raise ValueError(
            f"mesh {name}: {pinched} vertices join surface sheets that share no edge "
            "(non-manifold vertices); a geometry image needs a manifold surface"
        )


def _face_adjacency(faces: np.ndarray) -> scipy.sparse.csr_matrix:
    """Triangles sharing an edge, as a sparse ``(F, F)`` graph."""
    undirected = np.sort(edges_of(faces), axis=1)
    _, edge_id = np.unique(undirected, axis=0, return_inverse=True)
    owner = np.repeat(np.arange(len(faces)), 3)
    incidence = scipy.sparse.csr_matrix(
        (np.ones(len(owner)), (owner, edge_id.ravel())), shape=(len(faces), edge_id.max() + 1)
    )
    return (incidence @ incidence.T).tocsr()


def orient(vertices: np.ndarray, faces: np.ndarray, name: str) -> tuple[np.ndarray, np.ndarray]:
    """Consistent winding (libigl's BFS), outward for a closed surface, else the winding of
    the majority of the input triangles.

    Returns:
        the oriented faces and a ``(F,)`` mask of the triangles whose winding changed
        (``(a, b, c)`` became ``(a, c, b)``).
    """
    oriented, _ = igl.bfs_orient(faces)
    flipped = ~_same_winding(oriented, faces)
    directed = edges_of(np.where(flipped[:, None], faces[:, [0, 2, 1]], faces))
    if len(np.unique(directed, axis=0)) < len(directed):
        raise ValueError(
            f"mesh {name}: the surface is not orientable (like a Moebius strip); a geometry "
            "image needs two sides"
        )
    undirected = np.unique(np.sort(directed, axis=1), axis=0)
    closed = 2 * len(undirected) == len(directed)
    if closed:
        result = np.where(flipped[:, None], faces[:, [0, 2, 1]], faces)
        p = vertices[result]
        volume = np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum()
        if volume < 0:
            flipped = ~flipped
    elif flipped.sum() > len(faces) / 2:
        flipped = ~flipped
    return np.where(flipped[:, None], faces[:, [0, 2, 1]], faces), flipped


def _same_winding(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Whether triangles ``a`` and ``b`` (same vertex sets) wind the same way."""
    return (a == b).all(1) | (a == b[:, [1, 2, 0]]).all(1) | (a == b[:, [2, 0, 1]]).all(1)


def topology(faces: np.ndarray) -> tuple[int, int]:
    """Boundary loops and genus of a connected manifold surface (``V - E + F = 2 - 2 g - b``)."""
    loops = len(igl.boundary_loop_all(faces))
    undirected = np.unique(np.sort(edges_of(faces), axis=1), axis=0)
    euler = len(np.unique(faces)) - len(undirected) + len(faces)
    return loops, (2 - euler - loops) // 2


def genus0_cut(vertices: np.ndarray, faces: np.ndarray) -> list[int]:
    """Shortest edge path (by length) between the two extreme vertices along the longest
    principal axis of a closed genus-0 surface; at least two edges."""
    edges = np.unique(np.sort(edges_of(faces), axis=1), axis=0)
    length = np.linalg.norm(vertices[edges[:, 0]] - vertices[edges[:, 1]], axis=1)
    n = len(vertices)
    graph = scipy.sparse.coo_matrix((length + 1e-30, (edges[:, 0], edges[:, 1])), shape=(n, n))
    used = np.unique(faces)
    centred = vertices[used] - vertices[used].mean(0)
    axis = np.linalg.svd(centred, full_matrices=False)[2][0]
    start, end = used[np.argmin(centred @ axis)], used[np.argmax(centred @ axis)]
    _, pred = scipy.sparse.csgraph.dijkstra(
        graph, directed=False, indices=start, return_predecessors=True
    )
    path = [int(end)]
    while path[-1] != start:
        path.append(int(pred[path[-1]]))
    if len(path) < 3:  # one edge would open a two-vertex hole; go on to a third vertex
        ring = edges[(edges == path[0]).any(1)].ravel()
        path.insert(0, int(next(v for v in ring if v not in path)))
    return path[::-1]


def shortest_loops(vertices: np.ndarray, faces: np.ndarray) -> list[list[int]]:
    """The ``2 g`` loops of a closed genus-``g`` surface through one root vertex (the
    lower-left extreme, min x + y) that cut it into a disk, each as short as the greedy
    tree-cotree construction makes it (Erickson and Whittlesey 2005)."""
    edges, edge_id = np.unique(np.sort(edges_of(faces), axis=1), axis=0, return_inverse=True)
    edge_id = edge_id.reshape(-1, 3)
    n = len(vertices)
    length = np.linalg.norm(vertices[edges[:, 0]] - vertices[edges[:, 1]], axis=1)
    graph = scipy.sparse.coo_matrix((length + 1e-30, (edges[:, 0], edges[:, 1])), shape=(n, n))
    used = np.unique(faces)
    root = int(used[np.argmin(vertices[used, 0] + vertices[used, 1])])
    dist, pred = scipy.sparse.csgraph.dijkstra(
        graph, directed=False, indices=root, return_predecessors=True
    )
    key = edges @ [n, 1]
    child = np.nonzero(pred >= 0)[0]
    in_tree = np.isin(key, np.sort(np.stack([child, pred[child]], 1), axis=1) @ [n, 1])
    # The two triangles of every edge (closed manifold), then the dual spanning tree that
    # keeps the longest loops out of the cut: a maximum spanning tree of loop lengths.
    order = np.argsort(edge_id.ravel(), kind="stable")
    sides = (order // 3).reshape(-1, 2)
    loop_length = dist[edges[:, 0]] + length + dist[edges[:, 1]]
    free = np.nonzero(~in_tree)[0]
    weight = loop_length.max() + 1.0 - loop_length[free]
    dual = scipy.sparse.coo_matrix(
        (weight, (sides[free, 0], sides[free, 1])), shape=(len(faces), len(faces))
    )
    cotree = scipy.sparse.csgraph.minimum_spanning_tree(dual).tocoo()
    cotree_pairs = np.sort(np.stack([cotree.row, cotree.col], 1), axis=1) @ [len(faces), 1]
    in_cotree = np.isin(np.sort(sides, axis=1) @ [len(faces), 1], cotree_pairs) & ~in_tree

    def to_root(v: int) -> list[int]:
        path = [int(v)]
        while path[-1] != root:
            path.append(int(pred[path[-1]]))
        return path

    return [to_root(a)[::-1] + to_root(b) for a, b in edges[~in_tree & ~in_cotree]]


def cut_flags(faces: np.ndarray, cuts: list[list[int]]) -> np.ndarray:
    """``(F, 3)`` flags of the triangle edges ``(f_k, f_{k+1})`` on the cut paths."""
    on_cut = {tuple(sorted(e)) for path in cuts for e in zip(path[:-1], path[1:], strict=True)}
    edges = np.sort(edges_of(faces), axis=1).reshape(-1, 3, 2)
    return np.array([[(int(a), int(b)) in on_cut for a, b in tri] for tri in edges], dtype=bool)


def _weld_and_orient(
    vertices: np.ndarray, faces: np.ndarray, name: str
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """The welded, consistently oriented triangles ``(F', 3)``, the input faces they keep,
    which of them were flipped, and how many vertices were welded."""
    welded, kept, n_welded = weld(vertices, faces)
    if len(kept) == 0:
        raise ValueError(f"mesh {name}: every triangle has zero size")
    try:
        check_surface(welded, name)
        oriented, flipped = orient(vertices, welded, name)
    except ValueError as welded_error:
        # Welding glued a surface to itself (a parametric surface whose seam or pole
        # repeats vertices): keep the mesh as it came if that is one orientable surface.
        try:
            check_surface(faces, name)
            oriented, flipped = orient(vertices, faces, name)
        except ValueError:
            raise welded_error from None
        kept, n_welded = np.arange(len(faces)), 0
    return oriented, kept, flipped, n_welded


def _cut(
    vertices: np.ndarray, oriented: np.ndarray, loops: int, genus: int, name: str
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Cut a surface that is not yet a disk along seams (libigl's ``cut_to_disk`` with
    boundaries, shortest loops for handles, one path on a closed sphere).

    Returns:
        the cut mesh's vertices and faces, each cut vertex's source vertex, the cut
        vertices where seams and boundaries branch (anchors of the map) and the seam's
        edges ``(S, 2)`` in source vertices.
    """
    if loops:
        cuts = igl.cut_to_disk(oriented)
    elif genus:
        cuts = shortest_loops(vertices, oriented)
    else:
        cuts = [genus0_cut(vertices, oriented)]
    flags = cut_flags(oriented, cuts)
    cut_vertices, cut_faces, source = igl.cut_mesh(vertices, oriented, flags)
    boundary = {
        tuple(sorted(e))
        for loop in igl.boundary_loop_all(oriented)
        for e in zip(loop, np.roll(loop, -1), strict=True)
    }
    seam = {tuple(sorted(e)) for path in cuts for e in zip(path[:-1], path[1:], strict=True)}
    seam -= boundary
    graph = np.array(sorted(seam | boundary), dtype=np.int64).reshape(-1, 2)
    valence = np.bincount(graph.ravel(), minlength=len(vertices))
    node = (valence > 0) & (valence != 2)
    anchors = node[source] & np.isin(np.arange(len(source)), igl.boundary_loop(cut_faces))
    if topology(cut_faces) != (1, 0):
        raise RuntimeError(f"mesh {name}: cutting to a disk failed {topology(cut_faces)}")
    seam_edges = np.array(sorted(seam), dtype=np.int64).reshape(-1, 2)
    return cut_vertices, cut_faces, source, anchors, seam_edges


def to_disk(vertices: np.ndarray, faces: np.ndarray, name: str) -> DiskMesh:
    """Weld, check, orient and cut a mesh into a disk (see the module docstring).

    Args:
        vertices: ``(V, 3)`` positions.
        faces: ``(F, 3)`` triangles.
        name: the mesh's file or object name, for error messages.
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    if len(faces) == 0:
        raise ValueError(f"mesh {name}: no triangles found")
    oriented, kept, flipped, n_welded = _weld_and_orient(vertices, faces, name)
    corners = np.repeat(np.eye(3)[None], len(kept), axis=0)
    corners[flipped] = corners[flipped][:, [0, 2, 1]]
    loops, genus = topology(oriented)
    changes = {
        "welded_vertices": n_welded,
        "dropped_faces": len(faces) - len(kept),
        "reoriented_faces": int(flipped.sum()),
        "boundary_loops": loops,
        "genus": genus,
        "seam_edges": 0,
        "seam_length": 0.0,
    }
    anchors = np.zeros(len(vertices), bool)
    if loops == 1 and genus == 0:
        cut_vertices, cut_faces, source = vertices, oriented, np.arange(len(vertices))
    else:
        cut_vertices, cut_faces, source, anchors, seam_edges = _cut(
            vertices, oriented, loops, genus, name
        )
        length = np.linalg.norm(vertices[seam_edges[:, 0]] - vertices[seam_edges[:, 1]], axis=1)
        changes["seam_edges"] = len(seam_edges)
        changes["seam_length"] = float(length.sum() / bbox_diagonal(vertices[np.unique(faces)]))
    # Unreferenced vertices would make the map's linear systems singular.
    used = np.unique(cut_faces)
    if len(used) < len(cut_vertices):
        index = np.full(len(cut_vertices), -1)
        index[used] = np.arange(len(used))
        cut_vertices, cut_faces, source = cut_vertices[used], index[cut_faces], source[used]
        anchors = anchors[used]
    return DiskMesh(
        vertices=np.asarray(cut_vertices, dtype=np.float64),
        faces=np.asarray(cut_faces, dtype=np.int64),
        parent=kept,
        corners=corners,
        vertex_source=np.asarray(source, dtype=np.int64),
        anchors=anchors,
        changes=changes,
    )
