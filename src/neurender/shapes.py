"""Procedural shapes shared by several methods: an irregularly triangulated disk and a
face-like relief with blendshapes (DeepPRT's head; the detailed head of the simplification
stage adds skin detail to it).

World units, y up, the face looking along +z (relief height in z). Everything is
deterministic given the numpy generator passed in.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import scipy.spatial

BLENDSHAPES = (
    "smile",
    "frown",
    "jaw_open",
    "brow_raise",
    "cheek_puff",
    "nose_wrinkle",
    "eyes_close",
)


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


def gauss(x: np.ndarray, y: np.ndarray, cx: float, cy: float, sx: float, sy: float) -> np.ndarray:
    """Axis-aligned Gaussian bump of height 1 at ``(cx, cy)`` with widths ``(sx, sy)``."""
    return np.exp(-0.5 * (((x - cx) / sx) ** 2 + ((y - cy) / sy) ** 2))


def _head_relief(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Height z of the neutral face over the ellipse x in [-1, 1], y in [-1.3, 1.3]."""
    r2 = x**2 + (y / 1.3) ** 2
    z = 0.55 * np.sqrt(np.clip(1.0 - r2, 0.0, None))
    nose_ramp = np.clip((0.3 - y) / 0.55, 0.0, 1.0) * (y > -0.32)
    z += 0.34 * nose_ramp * np.exp(-0.5 * (x / (0.07 + 0.08 * nose_ramp)) ** 2)
    for sx in (-1, 1):
        z -= 0.2 * gauss(x, y, 0.36 * sx, 0.22, 0.14, 0.11)  # eye sockets
        z += 0.09 * gauss(x, y, 0.36 * sx, 0.44, 0.2, 0.06)  # brow ridges
        z += 0.09 * gauss(x, y, 0.5 * sx, -0.2, 0.18, 0.2)  # cheeks
    z += 0.07 * gauss(x, y, 0.0, -0.5, 0.2, 0.04)  # upper lip
    z += 0.06 * gauss(x, y, 0.0, -0.63, 0.18, 0.05)  # lower lip
    z -= 0.05 * gauss(x, y, 0.0, -0.565, 0.22, 0.02)  # mouth line
    z += 0.1 * gauss(x, y, 0.0, -0.95, 0.16, 0.12)  # chin
    return z


def _head_blendshape(name: str, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Full-weight displacement ``(V, 3)`` of a head blendshape at rest positions (x, y)."""
    d = np.zeros((len(x), 3))
    corners = sum(gauss(x, y, 0.22 * s, -0.56, 0.1, 0.08) for s in (-1, 1))
    if name == "smile":
        d[:, 1] += 0.1 * corners
        d[:, 0] += 0.06 * np.sign(x) * corners
        d[:, 2] += sum(0.08 * gauss(x, y, 0.45 * s, -0.3, 0.15, 0.15) for s in (-1, 1))
    elif name == "frown":
        d[:, 1] -= 0.1 * corners
        d[:, 2] -= 0.03 * corners
        d[:, 1] -= 0.06 * gauss(x, y, 0.0, 0.42, 0.25, 0.08)
        d[:, 2] += 0.05 * gauss(x, y, 0.0, 0.4, 0.12, 0.08)
    elif name == "jaw_open":
        jaw = np.clip((-0.52 - y) / 0.15, 0.0, 1.0) * np.exp(-0.5 * (x / 0.6) ** 2)
        d[:, 1] -= 0.28 * jaw
        d[:, 2] -= 0.12 * jaw
        d[:, 2] -= 0.12 * gauss(x, y, 0.0, -0.6, 0.16, 0.05)
    elif name == "brow_raise":
        d[:, 1] += sum(0.1 * gauss(x, y, 0.36 * s, 0.46, 0.25, 0.12) for s in (-1, 1))
        d[:, 2] += sum(0.04 * gauss(x, y, 0.36 * s, 0.46, 0.2, 0.06) for s in (-1, 1))
    elif name == "cheek_puff":
        d[:, 2] += sum(0.18 * gauss(x, y, 0.45 * s, -0.35, 0.2, 0.2) for s in (-1, 1))
    elif name == "nose_wrinkle":
        d[:, 2] += 0.06 * gauss(x, y, 0.0, 0.15, 0.12, 0.1) * (1.0 + np.sin(40.0 * y))
        d[:, 1] += 0.05 * gauss(x, y, 0.0, -0.2, 0.15, 0.1)
    elif name == "eyes_close":
        d[:, 2] += sum(0.17 * gauss(x, y, 0.36 * s, 0.22, 0.13, 0.1) for s in (-1, 1))
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
