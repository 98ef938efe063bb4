"""Mesh operations: quadric-error decimation (fast-simplification), UV atlases (xatlas),
and marching cubes of an implicit surface (scikit-image).

A :class:`LowPolyMesh` keeps the welded mesh the optimiser moves (``positions``, ``faces``)
and the atlas mesh the renderer draws, whose vertices are split along UV seams:
atlas vertex ``k`` sits at ``positions[vmap[k]]`` with texture coordinate ``uvs[k]``.
"""

from __future__ import annotations

import dataclasses

import fast_simplification
import numpy as np
import xatlas
from skimage.measure import marching_cubes

from neurender.geometry import vertex_normals


@dataclasses.dataclass
class LowPolyMesh:
    """Welded ``positions (V, 3)``, ``faces (F, 3)``; atlas ``vmap (A,)``, ``uvs (A, 2)``
    in [0, 1] and ``uv_faces (F, 3)`` indexing atlas vertices (same triangle order)."""

    positions: np.ndarray
    faces: np.ndarray
    vmap: np.ndarray
    uvs: np.ndarray
    uv_faces: np.ndarray

    def atlas_positions(self, positions: np.ndarray | None = None) -> np.ndarray:
        return (self.positions if positions is None else positions)[self.vmap]

    def atlas_normals(self, positions: np.ndarray | None = None) -> np.ndarray:
        """``(A, 3)`` area-weighted unit normals of the welded mesh at the atlas vertices.

        The normals must come from the welded mesh: the atlas mesh's own vertex normals
        would see only one chart's triangles at a seam and split the shading there."""
        welded = self.positions if positions is None else positions
        return vertex_normals(welded, self.faces)[self.vmap]


def decimate(vertices: np.ndarray, faces: np.ndarray, target_faces: int) -> tuple:
    """Quadric-error (Garland-Heckbert) decimation to about ``target_faces`` triangles.

    Returns:
        ``(V', 3)`` float64 positions and ``(F', 3)`` int64 faces, unreferenced vertices removed.
    """
    if target_faces >= len(faces):
        raise ValueError(f"target of {target_faces} triangles is not below the {len(faces)} given")
    v, f = fast_simplification.simplify(
        vertices.astype(np.float32), faces.astype(np.int32), target_count=target_faces
    )
    used, f = np.unique(f, return_inverse=True)
    return v[used].astype(np.float64), f.reshape(-1, 3).astype(np.int64)


def uv_atlas(positions: np.ndarray, faces: np.ndarray, texture_size: int) -> LowPolyMesh:
    """Chart the mesh and pack the charts into a square atlas with a 2-texel gutter."""
    atlas = xatlas.Atlas()
    atlas.add_mesh(positions.astype(np.float32), faces.astype(np.uint32))
    pack = xatlas.PackOptions()
    pack.resolution = texture_size
    pack.padding = 2
    pack.bilinear = True
    atlas.generate(pack_options=pack)
    vmap, uv_faces, uvs = atlas[0]
    return LowPolyMesh(
        positions.astype(np.float64),
        faces.astype(np.int64),
        vmap.astype(np.int64),
        uvs.astype(np.float64),
        uv_faces.astype(np.int64),
    )


def implicit_mesh(
    field_fn, bounds: tuple[np.ndarray, np.ndarray], resolution: int, level: float
) -> tuple[np.ndarray, np.ndarray]:
    """Marching-cubes mesh of ``{x : field_fn(x) = level}`` on a ``resolution^3`` grid.

    Args:
        field_fn: ``(N, 3)`` points -> ``(N,)`` field values, larger inside.
        bounds: min and max corners ``(3,)`` of the sampled box.

    Returns:
        ``(V, 3)`` positions and ``(F, 3)`` faces wound so normals point outwards.
    """
    lo, hi = (np.asarray(b, dtype=np.float64) for b in bounds)
    axes = [np.linspace(lo[i], hi[i], resolution) for i in range(3)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    values = field_fn(grid).reshape((resolution,) * 3)
    spacing = tuple((hi - lo) / (resolution - 1))
    verts, faces, _, _ = marching_cubes(values, level, spacing=spacing)
    # skimage orients faces towards increasing values (inside here): flip to point outwards.
    return verts + lo, faces[:, ::-1].astype(np.int64)
