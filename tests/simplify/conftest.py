import numpy as np
import pytest
import trimesh

from neurender.simplify import bake, mesh_ops


@pytest.fixture
def baked_plane():
    """Factory: a subdivided 2 x 2 plane facing +z with xatlas UVs and the normal map that
    bakes a constant world ``normal`` onto it: ``make(size, normal, subdivisions)`` ->
    ``(LowPolyMesh, (size, size, 3) normal map)``."""

    def make(size: int, normal, subdivisions: int):
        box = trimesh.creation.box([2.0, 2.0, 0.01])
        top = box.faces[(box.vertices[:, 2] > 0)[box.faces].all(1)]
        grid = trimesh.Trimesh(box.vertices, top)
        for _ in range(subdivisions):
            grid = grid.subdivide()
        grid.remove_unreferenced_vertices()
        low = mesh_ops.uv_atlas(np.asarray(grid.vertices), np.asarray(grid.faces), size)
        unit = np.asarray(normal, dtype=np.float64) / np.linalg.norm(normal)
        normal_map, _ = bake.bake(
            low,
            grid.vertices - [0, 0, 0.01],
            grid.faces,
            size,
            normal_fn=lambda p, f, b: np.tile(unit, (len(p), 1)),
        )
        return low, normal_map

    return make
