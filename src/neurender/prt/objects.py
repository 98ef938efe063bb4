"""Source meshes of the DeepPRT objects: procedural built-ins and validated user meshes.

All built-ins are open, disk-topology surfaces with real self-shadowing (concavities and
protrusions), deterministic from a seed, in world units with the object facing +z and y up:

* ``head``: face-like relief (nose, brow ridges, eye sockets, lips, cheeks, chin) with
  blendshape targets (:data:`BLENDSHAPES`), per-vertex deltas of the source mesh.
* ``creature``: an organic dome with random protrusions (stands in for the paper's fish),
  animated by a free-form-deformation lattice.
* ``cloth``: a flat square sheet, animated by a cloth simulation.
* ``plane``: the head's disk flattened to z = 0 (same parametrisation as ``head``), for the
  linear shape space of paper section 4.2.2.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import igl
import numpy as np
import scipy.spatial
import trimesh

BLENDSHAPES = (
    "smile",
    "frown",
    "jaw_open",
    "brow_raise",
    "cheek_puff",
    "nose_wrinkle",
    "eyes_close",
)
USER_MESH_SUFFIXES = (".obj", ".ply", ".stl", ".off")


@dataclasses.dataclass
class SourceMesh:
    """A disk-topology triangle mesh with optional blendshape deltas.

    Attributes:
        vertices: ``(V, 3)`` float64 positions.
        faces: ``(F, 3)`` int64 triangles.
        blendshapes: name -> ``(V, 3)`` displacement of the full-weight target.
    """

    vertices: np.ndarray
    faces: np.ndarray
    blendshapes: dict[str, np.ndarray] = dataclasses.field(default_factory=dict)


def disk_mesh(n_vertices: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Irregular Delaunay triangulation of the unit disk.

    Interior points are a jittered grid (so triangles are well shaped but not regular);
    the boundary is a circle of ``~sqrt(4 pi n)`` points.

    Returns:
        ``(V, 2)`` points and ``(F, 3)`` counter-clockwise triangles.
    """
    n_boundary = max(16, int(np.sqrt(4.0 * np.pi * n_vertices)))
    spacing = np.sqrt(np.pi / n_vertices)
    t = np.arange(-1.0, 1.0 + spacing, spacing)
    grid = np.stack(np.meshgrid(t, t), -1).reshape(-1, 2)
    grid += rng.uniform(-0.3, 0.3, grid.shape) * spacing
    interior = grid[np.linalg.norm(grid, axis=1) < 1.0 - 0.6 * spacing]
    angle = 2.0 * np.pi * np.arange(n_boundary) / n_boundary
    points = np.concatenate([np.stack([np.cos(angle), np.sin(angle)], 1), interior])
    faces = scipy.spatial.Delaunay(points).simplices.astype(np.int64)
    # Drop slivers Delaunay may create along the convex boundary.
    a, b, c = (points[faces[:, k]] for k in range(3))
    area = 0.5 * (
        (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    )
    faces[area < 0] = faces[area < 0][:, [0, 2, 1]]
    return points, faces[np.abs(area) > 1e-10]


def _gauss(x: np.ndarray, y: np.ndarray, cx: float, cy: float, sx: float, sy: float) -> np.ndarray:
    return np.exp(-0.5 * (((x - cx) / sx) ** 2 + ((y - cy) / sy) ** 2))


def _head_relief(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Height z of the neutral face over the ellipse x in [-1, 1], y in [-1.3, 1.3]."""
    r2 = x**2 + (y / 1.3) ** 2
    z = 0.55 * np.sqrt(np.clip(1.0 - r2, 0.0, None))
    nose_ramp = np.clip((0.3 - y) / 0.55, 0.0, 1.0) * (y > -0.32)
    z += 0.34 * nose_ramp * np.exp(-0.5 * (x / (0.07 + 0.08 * nose_ramp)) ** 2)
    for sx in (-1, 1):
        z -= 0.2 * _gauss(x, y, 0.36 * sx, 0.22, 0.14, 0.11)  # eye sockets
        z += 0.09 * _gauss(x, y, 0.36 * sx, 0.44, 0.2, 0.06)  # brow ridges
        z += 0.09 * _gauss(x, y, 0.5 * sx, -0.2, 0.18, 0.2)  # cheeks
    z += 0.07 * _gauss(x, y, 0.0, -0.5, 0.2, 0.04)  # upper lip
    z += 0.06 * _gauss(x, y, 0.0, -0.63, 0.18, 0.05)  # lower lip
    z -= 0.05 * _gauss(x, y, 0.0, -0.565, 0.22, 0.02)  # mouth line
    z += 0.1 * _gauss(x, y, 0.0, -0.95, 0.16, 0.12)  # chin
    return z


def _head_blendshape(name: str, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Full-weight displacement ``(V, 3)`` of a head blendshape at rest positions (x, y)."""
    d = np.zeros((len(x), 3))
    corners = sum(_gauss(x, y, 0.22 * s, -0.56, 0.1, 0.08) for s in (-1, 1))
    if name == "smile":
        d[:, 1] += 0.1 * corners
        d[:, 0] += 0.06 * np.sign(x) * corners
        d[:, 2] += sum(0.08 * _gauss(x, y, 0.45 * s, -0.3, 0.15, 0.15) for s in (-1, 1))
    elif name == "frown":
        d[:, 1] -= 0.1 * corners
        d[:, 2] -= 0.03 * corners
        d[:, 1] -= 0.06 * _gauss(x, y, 0.0, 0.42, 0.25, 0.08)
        d[:, 2] += 0.05 * _gauss(x, y, 0.0, 0.4, 0.12, 0.08)
    elif name == "jaw_open":
        jaw = np.clip((-0.52 - y) / 0.15, 0.0, 1.0) * np.exp(-0.5 * (x / 0.6) ** 2)
        d[:, 1] -= 0.28 * jaw
        d[:, 2] -= 0.12 * jaw
        d[:, 2] -= 0.12 * _gauss(x, y, 0.0, -0.6, 0.16, 0.05)
    elif name == "brow_raise":
        d[:, 1] += sum(0.1 * _gauss(x, y, 0.36 * s, 0.46, 0.25, 0.12) for s in (-1, 1))
        d[:, 2] += sum(0.04 * _gauss(x, y, 0.36 * s, 0.46, 0.2, 0.06) for s in (-1, 1))
    elif name == "cheek_puff":
        d[:, 2] += sum(0.18 * _gauss(x, y, 0.45 * s, -0.35, 0.2, 0.2) for s in (-1, 1))
    elif name == "nose_wrinkle":
        d[:, 2] += 0.06 * _gauss(x, y, 0.0, 0.15, 0.12, 0.1) * (1.0 + np.sin(40.0 * y))
        d[:, 1] += 0.05 * _gauss(x, y, 0.0, -0.2, 0.15, 0.1)
    elif name == "eyes_close":
        d[:, 2] += sum(0.17 * _gauss(x, y, 0.36 * s, 0.22, 0.13, 0.1) for s in (-1, 1))
    else:
        raise KeyError(f"unknown head blendshape {name!r}; expected one of {BLENDSHAPES}")
    return d


def head_mesh(n_vertices: int, rng: np.random.Generator) -> SourceMesh:
    """The procedural face with its blendshape targets (:data:`BLENDSHAPES`)."""
    points, faces = disk_mesh(n_vertices, rng)
    x, y = points[:, 0], 1.3 * points[:, 1]
    vertices = np.stack([x, y, _head_relief(x, y)], 1)
    shapes = {name: _head_blendshape(name, x, y) for name in BLENDSHAPES}
    return SourceMesh(vertices, faces, shapes)


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
        z += rng.uniform(0.25, 0.45) * _gauss(
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
    """Raise ``ValueError`` naming ``name`` unless the mesh is one manifold disk."""
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
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


def load_user_mesh(path: str | Path) -> SourceMesh:
    """Load an OBJ/PLY/STL/OFF mesh and check it has disk topology (errors name the file)."""
    p = Path(path)
    if p.suffix.lower() not in USER_MESH_SUFFIXES:
        raise ValueError(
            f"mesh {p}: unsupported format {p.suffix!r}; expected one of {USER_MESH_SUFFIXES}"
        )
    if not p.is_file():
        raise FileNotFoundError(f"mesh file {p} does not exist")
    try:
        mesh = trimesh.load(p, force="mesh", process=True)
    except Exception as err:
        raise OSError(f"cannot read mesh file {p}: {err}") from err
    if len(mesh.faces) == 0:
        raise ValueError(f"mesh {p}: no triangles found")
    mesh.remove_unreferenced_vertices()
    vertices, faces = np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces, np.int64)
    check_disk_topology(vertices, faces, str(p))
    return SourceMesh(vertices, faces)


def source_mesh(name: str, n_vertices: int, seed: int, user_path: str | None = None) -> SourceMesh:
    """The source mesh of a built-in object or a user mesh file."""
    if user_path is not None:
        return load_user_mesh(user_path)
    if name not in BUILTIN:
        raise KeyError(f"unknown object {name!r}; built-ins are {sorted(BUILTIN)}")
    # The plane shares the head's seed so both have the same triangulation.
    key = "head" if name == "plane" else name
    rng = np.random.default_rng([seed, sorted(BUILTIN).index(key)])
    mesh = BUILTIN[name](n_vertices, rng)
    check_disk_topology(mesh.vertices, mesh.faces, name)
    return mesh
