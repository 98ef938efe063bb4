import numpy as np
import pytest
import trimesh
from PIL import Image

from neurender.simplification import bake, mesh_ops


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


@pytest.fixture(scope="session")
def bumpy_glb(tmp_path_factory):
    """A detailed textured asset written by trimesh: an icosphere (5120 triangles) with
    bumps finer than a 5 % decimation keeps, spherical UVs, an 8-bit base-colour texture
    of blotches and stripes, as GLB; the file's path."""
    sphere = trimesh.creation.icosphere(subdivisions=4)
    v = np.asarray(sphere.vertices)
    vertices = v * (1 + 0.05 * np.sin(9 * v[:, :1]) * np.cos(7 * v[:, 1:2]) + 0.03 * v[:, 2:])
    uv = np.column_stack(
        [0.5 + np.arctan2(v[:, 0], v[:, 2]) / (2 * np.pi), 1 - np.arccos(v[:, 1]) / np.pi]
    )
    u, w = np.meshgrid(np.linspace(0, 1, 64), np.linspace(0, 1, 64))
    texture = np.stack(
        [0.5 + 0.4 * np.sin(12 * u), 0.4 + 0.3 * np.cos(9 * w), 0.3 + 0.2 * u * w], -1
    )
    material = trimesh.visual.material.PBRMaterial(
        baseColorTexture=Image.fromarray(np.round(texture * 255).astype(np.uint8))
    )
    mesh = trimesh.Trimesh(vertices, sphere.faces, process=False)
    mesh.visual = trimesh.visual.TextureVisuals(uv=uv, material=material)
    path = tmp_path_factory.mktemp("assets") / "bumpy.glb"
    mesh.export(path)
    return path


@pytest.fixture
def stage_cfg():
    """The simplification keys the jobs read, at test sizes (32 px, 32^2 textures, few views)."""
    return dict(
        seed=0,
        device="cpu",
        intensity=70.0,
        resolution=32,
        texture_size=32,
        train_views=4,
        test_views=3,
        reference_spp=8,
        test_spp=32,
        eval_spp=32,
        supersample=2,
        camera_distance=6.5,
        fov=30.0,
        light_distance=6.0,
        light_cone=50.0,
        steps=4,
        batch=1,
        spp=4,
        lr_positions=0.001,
        lr_textures=0.01,
        lr_final_fraction=0.05,
        laplacian_scale=0.25,
        laplacian_min_fraction=0.02,
    )
