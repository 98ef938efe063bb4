"""Source meshes of the DeepPRT objects: procedural built-ins and user mesh files.

All built-ins are open, disk-topology surfaces with real self-shadowing (concavities and
protrusions), deterministic from a seed, in world units with the object facing +z and y up:

* ``head``: the face relief with blendshapes of :func:`neurender.shapes.head_mesh`.
* ``creature``: an organic dome with random protrusions (stands in for the paper's fish),
  animated by a free-form-deformation lattice.
* ``cloth``: a flat square sheet, animated by a cloth simulation.
* ``plane``: the head's disk flattened to z = 0 (same parametrisation as ``head``), for the
  linear shape space of paper section 4.2.2.

User meshes (``prt.user_meshes``, and every frame of ``prt.user_sequences``) are read as
stored (:func:`read_mesh`): any single connected surface, open or closed, of any genus;
:mod:`neurender.prt.disk` makes it a disk. Positions stay in the file's place and units,
in float32 from the geometry image on: :func:`check_placement` warns about a mesh so far
from the origin (georeferenced coordinates) that float32 rounds away its shape.
"""

from __future__ import annotations

import logging
from pathlib import Path

import igl
import numpy as np
import scipy.spatial
import trimesh

from neurender import mesh_file
from neurender.geometry import float32_rounding
from neurender.prt import MESH_SUFFIXES, VTK_SUFFIXES
from neurender.shapes import SourceMesh, disk_mesh, gauss, head_mesh

log = logging.getLogger(__name__)

#: Largest float32 rounding of a user mesh's positions, as a fraction of its size, that
#: :func:`check_placement` lets pass (a 2 m mesh about 5 km from the origin).
FLOAT32_TOLERANCE = 1e-4


def plane_mesh(n_vertices: int, rng: np.random.Generator) -> SourceMesh:
    """The head's source mesh flattened to z = 0 (same vertices, faces and parametrisation)."""
    head = head_mesh(n_vertices, rng)
    flat = head.vertices.copy()
    flat[:, 2] = 0.0
    return SourceMesh(flat, head.faces)


def creature_mesh(n_vertices: int, rng: np.random.Generator) -> SourceMesh:
    """An organic dome with a dorsal ridge and 5-7 random protrusions."""
    points, faces = disk_mesh(n_vertices, rng)
    x, y = 1.4 * points[:, 0], 0.9 * points[:, 1]
    r2 = (x / 1.4) ** 2 + (y / 0.9) ** 2
    z = 0.5 * np.sqrt(np.clip(1.0 - r2, 0.0, None))
    z += 0.18 * np.exp(-0.5 * (y / 0.08) ** 2) * np.clip(1.0 - (x / 1.2) ** 2, 0.0, None)
    for _ in range(int(rng.integers(5, 8))):
        angle, radius = rng.uniform(0, 2 * np.pi), rng.uniform(0.25, 0.75)
        cx, cy = 1.4 * radius * np.cos(angle), 0.9 * radius * np.sin(angle)
        z += rng.uniform(0.25, 0.45) * gauss(
            x, y, cx, cy, rng.uniform(0.07, 0.12), rng.uniform(0.07, 0.12)
        )
    return SourceMesh(np.stack([x, y, z], 1), faces)


def cloth_mesh(n_vertices: int, rng: np.random.Generator) -> SourceMesh:
    """A flat 2 x 2 square in the z = 0 plane, irregularly triangulated."""
    side = max(4, int(np.sqrt(n_vertices)))
    t = np.linspace(-1.0, 1.0, side)
    grid = np.stack(np.meshgrid(t, t), -1).reshape(-1, 2)
    inner = (np.abs(grid) < 1.0 - 1e-9).all(axis=1)
    grid[inner] += rng.uniform(-0.25, 0.25, (inner.sum(), 2)) * (t[1] - t[0])
    faces = scipy.spatial.Delaunay(grid).simplices.astype(np.int64)
    a, b, c = (grid[faces[:, k]] for k in range(3))
    area = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    faces[area < 0] = faces[area < 0][:, [0, 2, 1]]
    return SourceMesh(np.column_stack([grid, np.zeros(len(grid))]), faces[np.abs(area) > 1e-12])


BUILTIN = {"head": head_mesh, "creature": creature_mesh, "cloth": cloth_mesh, "plane": plane_mesh}


def check_disk_topology(vertices: np.ndarray, faces: np.ndarray, name: str) -> None:
    """Raise ``ValueError`` naming ``name`` unless the mesh is one manifold disk: one
    component, one boundary loop and Euler characteristic ``V - E + F = 1`` (a torus with
    a hole has one component and one boundary loop too, but ``V - E + F = -1``: genus 1)."""
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    unique, counts = np.unique(edges, axis=0, return_counts=True)
    non_manifold = int((counts > 2).sum())
    components = len(
        trimesh.graph.connected_components(
            trimesh.graph.face_adjacency(faces), nodes=np.arange(len(faces))
        )
    )
    loops = len(igl.boundary_loop_all(faces)) if non_manifold == 0 else -1
    if components != 1 or loops != 1 or non_manifold:
        raise ValueError(
            f"mesh {name}: found {components} connected components, "
            f"{loops if loops >= 0 else 'undetermined'} boundary loops and "
            f"{non_manifold} non-manifold edges; a geometry image needs one connected surface "
            "with exactly one boundary loop (disk topology)"
        )
    used = len(np.unique(faces))
    euler = used - len(unique) + len(faces)
    if euler != 1:
        raise ValueError(
            f"mesh {name}: one component with one boundary loop, but Euler characteristic "
            f"V - E + F = {used} - {len(unique)} + {len(faces)} = {euler}, so genus "
            f"{(1 - euler) // 2}; a geometry image needs a disk (V - E + F = 1)"
        )


def read_mesh(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """Vertices ``(V, 3)`` float64 and triangles ``(F, 3)`` int64 of a mesh file as stored,
    every mesh of the file together (:func:`neurender.mesh_file.read`, geometry only,
    without the vertices no triangle uses, in the file's winding).

    Raises:
        AssetFileError: naming the file: an unknown format, no such file, an unreadable
            file, no triangles, face indices out of range, non-finite positions, a
            degenerate bounding box.
    """
    # The winding as stored: the geometry-image job orients the rest frame once
    # (:func:`neurender.prt.disk.orient`) and carries it to every frame, where orienting
    # each frame file on its own could wind frames differently.
    return mesh_file.read(
        path, MESH_SUFFIXES + VTK_SUFFIXES, materials=False, orient=False
    ).merged()


def load_user_mesh(path: str | Path) -> SourceMesh:
    """A user's mesh file as stored (:func:`read_mesh`); the geometry-image job welds,
    checks and cuts it into a disk (:func:`neurender.prt.disk.to_disk`)."""
    return SourceMesh(*read_mesh(path))


def check_placement(vertices: np.ndarray, where: str) -> None:
    """Warn, naming ``where`` (the file and its config key), where float32, in which DeepPRT
    keeps positions from the geometry image on (the ``rest`` geometry image, ray-traced
    transfer, the network's P input, the report's viewer), rounds ``vertices (V, 3)`` by
    more than :data:`FLOAT32_TOLERANCE` of their bounding box's longest side."""
    rounding = float32_rounding(vertices)
    if rounding > FLOAT32_TOLERANCE:
        far, side = float(np.abs(vertices).max()), float(np.ptp(vertices, axis=0).max())
        log.warning(
            "%s: a coordinate of %.6g, %.3g times the mesh's size (%.3g); DeepPRT keeps "
            "positions in float32, which rounds them by up to %.2g%% of that size: move the "
            "mesh near the origin in the file (subtract its centre) to keep its shape",
            where,
            far,
            far / side,
            side,
            100 * rounding,
        )


def source_mesh(name: str, n_vertices: int, seed: int) -> SourceMesh:
    """The source mesh of a built-in object (user meshes: :func:`load_user_mesh`)."""
    if name not in BUILTIN:
        raise KeyError(f"unknown object {name!r}; built-ins are {sorted(BUILTIN)}")
    # The plane shares the head's seed so both have the same triangulation.
    key = "head" if name == "plane" else name
    rng = np.random.default_rng([seed, sorted(BUILTIN).index(key)])
    mesh = BUILTIN[name](n_vertices, rng)
    check_disk_topology(mesh.vertices, mesh.faces, name)
    return mesh
