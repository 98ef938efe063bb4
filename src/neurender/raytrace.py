"""Ray tracing triangle meshes with Embree (embreex): scenes, occlusion and first hits.

Rays are ``(R, 3)`` origins and directions in world units (directions need not be unit
length; ``tfar`` is then in units of the direction's length). Embree has no ``tnear``:
a ray that starts on a surface must be offset from it by the caller. Barycentrics follow
Embree: a hit at ``(u, v)`` on triangle ``(a, b, c)`` is ``(1 - u - v) a + u b + v c``.
"""

from __future__ import annotations

import dataclasses
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from embreex import rtcore_scene
from embreex.mesh_construction import TriangleMesh


def embree_scene(vertices: np.ndarray, faces: np.ndarray) -> rtcore_scene.EmbreeScene:
    """An Embree scene of one triangle mesh ``(V, 3)``, ``(F, 3)``, its BVH already built."""
    scene = rtcore_scene.EmbreeScene()
    TriangleMesh(
        scene, np.ascontiguousarray(vertices, np.float32), np.ascontiguousarray(faces, np.int32)
    )
    probe = np.zeros((1, 3), np.float32)
    scene.run(probe, probe + np.float32([0, 0, 1]), query="OCCLUDED")  # builds the BVH once
    return scene


def occluded(
    vertices: np.ndarray, faces: np.ndarray, origins: np.ndarray, dirs: np.ndarray, threads: int = 1
) -> np.ndarray:
    """Embree occlusion test of rays against a triangle mesh.

    Args:
        vertices: ``(V, 3)`` mesh positions; faces: ``(F, 3)`` triangles.
        origins, dirs: ``(R, 3)`` rays; rays run to infinity.
        threads: rays are split into this many contiguous chunks traced concurrently
            (Embree's ``run`` releases the GIL).

    Returns:
        ``(R,)`` bool, True where the ray hits the mesh.
    """
    scene = embree_scene(vertices, faces)
    origins = np.ascontiguousarray(origins, np.float32)
    dirs = np.ascontiguousarray(dirs, np.float32)
    bounds = np.linspace(0, len(origins), max(threads, 1) + 1).astype(int)
    with ThreadPoolExecutor(max(threads, 1)) as pool:
        parts = pool.map(
            lambda ab: scene.run(origins[ab[0] : ab[1]], dirs[ab[0] : ab[1]], query="OCCLUDED"),
            zip(bounds[:-1], bounds[1:], strict=True),
        )
        return np.concatenate(list(parts)) != -1


@dataclasses.dataclass
class Hits:
    """First hits of ``R`` rays on a mesh.

    Attributes:
        mask: ``(R,)`` bool, the rays that hit.
        face: ``(R,)`` int hit triangle (-1 for a miss).
        distance: ``(R,)`` float32 ray parameter of the hit (``inf`` for a miss).
        corners: ``(M, 3)`` vertex indices of the hit triangles (``M`` = hits).
        bary: ``(M, 3)`` float32 barycentric weights of the hits.
    """

    mask: np.ndarray
    face: np.ndarray
    distance: np.ndarray
    corners: np.ndarray
    bary: np.ndarray

    def interpolate(self, values: np.ndarray) -> np.ndarray:
        """Per-vertex ``values`` ``(V, ...)`` at the hits, ``(R, C)`` float32, 0 for misses."""
        values = values.reshape(len(values), -1)
        out = np.zeros((len(self.mask), values.shape[1]), np.float32)
        out[self.mask] = np.einsum("pk,pkc->pc", self.bary, values[self.corners])
        return out

    def points(self, vertices: np.ndarray) -> np.ndarray:
        """World positions ``(M, 3)`` of the hits, from the barycentrics."""
        return np.einsum("kj,kjc->kc", self.bary, vertices[self.corners])


def first_hits(
    scene: rtcore_scene.EmbreeScene, faces: np.ndarray, origins: np.ndarray, dirs: np.ndarray
) -> Hits:
    """Nearest hit of every ray ``(R, 3)`` in ``scene`` (the mesh with ``faces``)."""
    out = scene.run(
        np.ascontiguousarray(origins, np.float32), np.ascontiguousarray(dirs, np.float32), output=1
    )
    face = out["primID"]
    mask = face >= 0
    u, v = out["u"], out["v"]
    return Hits(
        mask=mask,
        face=face,
        distance=np.where(mask, out["tfar"], np.float32(np.inf)),
        corners=faces[face[mask]],
        bary=np.stack([1 - u - v, u, v], -1)[mask],
    )
