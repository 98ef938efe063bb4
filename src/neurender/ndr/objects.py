"""Procedural objects in the manner of Xu et al. 2018: displaced primitives with SVBRDFs.

An object is the union (not a boolean merge) of 1 to 9 primitives (ellipsoid, box,
cylinder), each displaced along its vertex normals by a smooth noise height field,
scaled, rotated and translated so the parts cluster and occlude each other, then
normalised to fit the unit sphere. Materials are per-vertex, one random family per part,
spatially varied by 3-D fractal noise (FastNoise Lite) evaluated at the rest positions:

* ``albedo_diffuse`` ``(V, 3)`` linear RGB in [0, 1];
* ``albedo_specular`` ``(V, 3)`` linear RGB in [0, 1] (the specular lobe's scale, so that
  ``I_R = I_S * A_S + I_D * A_D`` holds exactly, paper eq. 2);
* ``roughness`` ``(V,)`` perceptual roughness in [0.05, 1] (GGX ``alpha = roughness^2``,
  Karis 2013).
"""

from __future__ import annotations

import colorsys
import dataclasses
import functools
import math

import numpy as np
import trimesh
from pyfastnoiselite.pyfastnoiselite import FastNoiseLite, FractalType, NoiseType

from neurender.geometry import vertex_normals

PRIMITIVES = ("ellipsoid", "box", "cylinder")


@dataclasses.dataclass
class ProceduralObject:
    """A triangle mesh with per-vertex materials; all arrays float32 except ``faces``."""

    vertices: np.ndarray  # (V, 3) world units, inside the unit sphere
    faces: np.ndarray  # (F, 3) int32
    albedo_diffuse: np.ndarray  # (V, 3)
    albedo_specular: np.ndarray  # (V, 3)
    roughness: np.ndarray  # (V,)
    n_primitives: int

    @functools.cached_property
    def normals(self) -> np.ndarray:
        """Area-weighted unit vertex normals ``(V, 3)`` float64: what Mitsuba shades with
        and the G-buffers store (computed once per object)."""
        return vertex_normals(self.vertices.astype(np.float64), self.faces)


def fractal_noise(points: np.ndarray, seed: int, frequency: float, octaves: int = 4) -> np.ndarray:
    """OpenSimplex2 fBm at ``points`` ``(N, 3)``: ``(N,)`` float32 in about [-1, 1]."""
    noise = FastNoiseLite(int(seed) % 2**31)
    noise.noise_type = NoiseType.NoiseType_OpenSimplex2
    noise.fractal_type = FractalType.FractalType_FBm
    noise.fractal_octaves = octaves
    noise.frequency = frequency
    coords = np.ascontiguousarray(np.asarray(points, np.float32).T)
    return np.asarray(noise.gen_from_coords(coords), np.float32)


@functools.lru_cache(maxsize=16)
def primitive_mesh(kind: str, edge: float) -> trimesh.Trimesh:
    """A watertight primitive of size about 2, with shared vertices and no edge longer than
    ``edge`` (vertex density sets how fine displacement and textures can be).

    Cached: treat the result as read-only.
    """
    if kind == "ellipsoid":
        mesh = trimesh.creation.icosphere(subdivisions=max(1, math.ceil(math.log2(1.2 / edge))))
    elif kind == "box":
        mesh = trimesh.creation.box(extents=(1.6, 1.6, 1.6))
    elif kind == "cylinder":
        mesh = trimesh.creation.cylinder(
            radius=0.9, height=1.8, sections=max(16, math.ceil(2 * math.pi * 0.9 / edge))
        )
    else:
        raise ValueError(f"unknown primitive {kind!r}; expected one of {PRIMITIVES}")
    vertices, faces = trimesh.remesh.subdivide_to_size(mesh.vertices, mesh.faces, edge)
    mesh = trimesh.Trimesh(vertices, faces, process=True)
    mesh.merge_vertices()
    return mesh


def _random_rotation(rng: np.random.Generator) -> np.ndarray:
    q = rng.normal(size=4)
    return trimesh.transformations.quaternion_matrix(q / np.linalg.norm(q))[:3, :3]


def _material(rng: np.random.Generator, points: np.ndarray, seed: int):
    """One part's per-vertex (albedo_diffuse, albedo_specular, roughness)."""
    n_vertices = len(points)
    frequency = rng.uniform(1.5, 8.0)
    mix = 0.5 + 0.5 * fractal_noise(points, seed, frequency)
    if rng.uniform() < 0.3:  # hard-edged patterns (spots, stripes) as well as smooth ones
        mix = (mix > rng.uniform(0.4, 0.6)).astype(np.float32)

    def colour(saturation_max: float) -> np.ndarray:
        h, s, v = rng.uniform(), rng.uniform(0, saturation_max), rng.uniform(0.15, 0.95)
        return np.array(colorsys.hsv_to_rgb(h, s, v), np.float32)

    diffuse = np.outer(1 - mix, colour(0.9)) + np.outer(mix, colour(0.9))
    metal = rng.uniform() < 0.2
    spec_level = rng.uniform(0.5, 1.0) if metal else rng.uniform(0.02, 0.5)
    spec_colour = colour(0.6) if metal else np.ones(3, np.float32)
    spec_mod = 1.0 - 0.5 * mix * rng.uniform()
    specular = np.outer(spec_mod, spec_colour * spec_level)
    if metal:
        diffuse *= 0.2
    r0, r1 = sorted(rng.uniform(0.05, 1.0, size=2))
    rough_noise = 0.5 + 0.5 * fractal_noise(points, seed + 1, rng.uniform(1.5, 8.0))
    roughness = r0 + (r1 - r0) * rough_noise
    return (
        np.clip(diffuse, 0, 1).astype(np.float32),
        np.clip(specular, 0, 1).astype(np.float32),
        np.clip(roughness, 0.05, 1.0).astype(np.float32).reshape(n_vertices),
    )


def random_object(
    rng: np.random.Generator,
    primitives: tuple[int, int],
    edge: float,
    diffuse_only: bool = False,
) -> ProceduralObject:
    """One random object with ``primitives[0]..primitives[1]`` parts (inclusive), each
    tessellated to ``edge`` (see :func:`primitive_mesh`) before scaling.

    ``diffuse_only`` zeroes the specular albedo (the paper's "diffuse material" dataset).
    """
    lo, hi = primitives
    if not 1 <= lo <= hi:
        raise ValueError(f"primitives={primitives}: expected 1 <= min <= max")
    count = int(rng.integers(lo, hi + 1))
    parts_v, parts_f, parts_ad, parts_as, parts_r = [], [], [], [], []
    offset = 0
    for i in range(count):
        mesh = primitive_mesh(PRIMITIVES[rng.integers(len(PRIMITIVES))], edge)
        rest = np.asarray(mesh.vertices, np.float64)
        normals = np.asarray(mesh.vertex_normals, np.float64)
        seed = int(rng.integers(2**31))
        height = fractal_noise(rest, seed, rng.uniform(1.0, 4.0), octaves=3)
        rest = rest + normals * (rng.uniform(0.02, 0.15) * height)[:, None]
        scale = rng.uniform(0.25, 0.7, size=3)
        # Later parts sit near earlier ones so the object self-occludes.
        centre = rng.normal(scale=0.35, size=3) if i else np.zeros(3)
        world = (rest * scale) @ _random_rotation(rng).T + centre
        ad, as_, r = _material(rng, rest, seed + 7)
        parts_v.append(world)
        parts_f.append(np.asarray(mesh.faces) + offset)
        parts_ad.append(ad)
        parts_as.append(as_)
        parts_r.append(r)
        offset += len(world)
    vertices = np.concatenate(parts_v)
    centre = (vertices.min(0) + vertices.max(0)) / 2
    vertices = vertices - centre
    vertices /= np.linalg.norm(vertices, axis=1).max()
    specular = np.concatenate(parts_as)
    return ProceduralObject(
        vertices=vertices.astype(np.float32),
        faces=np.concatenate(parts_f).astype(np.int32),
        albedo_diffuse=np.concatenate(parts_ad),
        albedo_specular=np.zeros_like(specular) if diffuse_only else specular,
        roughness=np.concatenate(parts_r),
        n_primitives=count,
    )
