"""The reference assets of the simplification stage (paper 4.1 and 4.5).

* ``head``: the DeepPRT face relief (:func:`neurender.shapes.head_mesh`) with skin
  detail (forehead wrinkles, crow's feet, pores) far finer than a 1-5 % decimation can keep;
  an open disk-topology surface facing +z, about 2 x 2.6 units, y up; grey Lambertian,
  rendered by Mitsuba.
* ``metaballs``: a blob creature of coloured metaballs centred at the origin, an implicit
  surface ``F = 1`` of :mod:`neurender.metaball`, rendered by its own ray marcher
  (:mod:`neurender.simplification.implicit`).
* a user asset (``simplification.user_assets``): a mesh file with its material
  (:mod:`neurender.simplification.user_mesh`), moved and scaled uniformly so that its bounding
  box is centred at the origin with a half-diagonal of :data:`USER_RADIUS`, rendered by
  Mitsuba with its own albedo (grey Lambertian where the file has none).

An :class:`Asset` is what the stage needs of either: the detailed triangle surface that
QEM and the classic baker start from, the reference renderer, the colour and normal the
baker reads at a surface point, its albedo where that is uniform, and where the cameras
may stand. World space is
right-handed, y up, units are the assets' own (no physical scale).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from types import ModuleType

import numpy as np
import torch
import trimesh

from neurender import mitsuba_setup
from neurender.asset_files import AssetFileError
from neurender.metaball import Scene, field, surface_attributes
from neurender.rng import stable_seed
from neurender.shapes import head_mesh
from neurender.simplification import CASES, SEED_SALT, implicit, mesh_ops, render, user_mesh
from neurender.simplification.bake import AttributeFn
from neurender.simplification.views import View

CREATURE_RADIUS = 1.7
HEAD_ALBEDO = 0.8
#: Held-out references are rendered with seed ``seed + TEST_SEED_OFFSET`` (a prime), so
#: their Monte Carlo noise is independent of the training references'.
TEST_SEED_OFFSET = 7919
#: Half-diagonal of a user asset's bounding box in the stage's frame: within the default
#: 30-degree view at distance 6.5 (half-height 1.74), like the head and the creature.
USER_RADIUS = 1.6
#: Camera azimuth and elevation ranges in degrees: an open relief is seen from its front
#: half-space, a closed object from all around.
VIEW_RANGES = {
    "front": ((-80.0, 80.0), (-35.0, 45.0)),
    "all_around": ((-180.0, 180.0), (-60.0, 70.0)),
}


def skin_detail(x: np.ndarray, y: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Height offsets ``(V,)`` of skin detail at face coordinates x in [-1, 1], y in
    [-1.3, 1.3]: forehead wrinkles (0.16 wavelength, 0.02 deep), crow's feet and random
    bumps (sigma 0.05): a few pixels wide at the default 128 px, finer than the triangles
    of a 1-5 % decimation, coarser than a 128^2 normal map's texels."""
    forehead = np.exp(-0.5 * ((y - 0.8) / 0.22) ** 2) * np.exp(-0.5 * (x / 0.55) ** 2)
    z = 0.02 * forehead * np.sin(2 * np.pi * y / 0.16 + 3.0 * x**2)
    for side in (-1, 1):  # crow's feet fan out from the outer eye corners
        dx, dy = x - 0.62 * side, y - 0.22
        fan = np.exp(-0.5 * (dx**2 + dy**2) / 0.15**2)
        z += 0.015 * fan * np.sin(np.arctan2(dy, dx * side) * 6.0)
    centres = rng.uniform([-1.0, -1.3], [1.0, 1.3], (150, 2))
    heights = rng.uniform(-0.02, 0.02, 150)
    d2 = (x[:, None] - centres[None, :, 0]) ** 2 + (y[:, None] - centres[None, :, 1]) ** 2
    z += (heights * np.exp(-0.5 * d2 / 0.05**2)).sum(1)
    return z


def detailed_head(n_vertices: int, seed: int) -> trimesh.Trimesh:
    """The high-resolution head, ``~2 n_vertices`` triangles, with smooth vertex normals."""
    rng = np.random.default_rng(stable_seed(seed, SEED_SALT, "head"))
    source = head_mesh(n_vertices, rng)
    v = source.vertices.copy()
    v[:, 2] += skin_detail(v[:, 0], v[:, 1], rng)
    # Centre the relief's depth so cameras orbit the middle of the object.
    v[:, 2] -= 0.5 * (v[:, 2].min() + v[:, 2].max())
    return trimesh.Trimesh(v, source.faces, process=False)


def metaball_creature(count: int, seed: int) -> Scene:
    """``count`` coloured balls around the origin (a body with limbs) within a radius of
    about :data:`CREATURE_RADIUS`, float64."""
    g = torch.Generator().manual_seed(stable_seed(seed, SEED_SALT, "metaballs")[0])
    u = torch.rand(count, 7, generator=g, dtype=torch.float64)
    # Balls on a random walk from the origin, so the surface is one connected blob.
    steps = (u[:, :3] * 2 - 1) * 0.55
    centres = torch.cumsum(steps, 0)
    centres = centres - centres.mean(0)
    radii = 0.22 + 0.2 * u[:, 3]
    # F = sum r^2 / d^2 is scale invariant: scale the creature to a fixed size, so one
    # camera distance frames both use cases (a ball's surface reaches ~1.3 r beyond its
    # centre where neighbours add to the field).
    scale = CREATURE_RADIUS / float((centres.norm(dim=1) + 1.3 * radii).max())
    return Scene(centres * scale, radii * scale, u[:, 4:7] * 0.8 + 0.1)


def reference_seed(seed: int, split: str) -> int:
    """The render seed of a split's Mitsuba references (:data:`TEST_SEED_OFFSET`)."""
    return seed + TEST_SEED_OFFSET * (split == "test")


@dataclasses.dataclass
class Asset:
    """A detailed asset as the stage sees it.

    Attributes:
        vertices, faces: ``(V, 3)``, ``(F, 3)`` detailed surface (QEM and the baker start here).
        triangles: the simplified mesh's triangle budget.
        views: a key of :data:`VIEW_RANGES`.
        colour_fn, normal_fn: what the classic baker reads at a detailed-surface hit
            (None: no colour map; the detailed mesh's interpolated vertex normals).
        references: ``(mi, views, split) -> (N, W, W, 4)`` reference renders (linear RGB,
            alpha = coverage) with the settings the asset was loaded with.
        albedo: the uniform grey albedo of an asset whose material is uniform (the head;
            its baselines and the viewer use it and it is not optimised); None where the
            colour varies (a texture is baked and optimised).
        to_asset: ``(4, 4)`` from the stage's frame back to the asset file's (uniform
            scale and translation); None for the built-in cases, made in the stage's frame.
        source: a user asset's parts with their materials, in the stage's frame; None
            for the built-in cases.
    """

    vertices: np.ndarray
    faces: np.ndarray
    triangles: int
    views: str
    colour_fn: AttributeFn | None
    normal_fn: AttributeFn | None
    references: Callable[[ModuleType, list[View], str], np.ndarray]
    albedo: float | None = None
    to_asset: np.ndarray | None = None
    source: user_mesh.UserMesh | None = None


def head_asset(cfg: dict) -> Asset:
    """The detailed head, rendered by Mitsuba (``reference_spp`` for training views,
    ``test_spp`` for held-out ones)."""
    detail = detailed_head(cfg["head_vertices"], cfg["seed"])

    def references(mi: ModuleType, views: list[View], split: str) -> np.ndarray:
        shape = mitsuba_setup.mesh(
            mi, detail.vertices, detail.faces, render.material(mi, HEAD_ALBEDO)
        )
        spp = cfg["test_spp"] if split == "test" else cfg["reference_spp"]
        seed = reference_seed(cfg["seed"], split)
        return render.render_views(
            mi, shape, views, cfg["resolution"], spp, cfg["intensity"], seed, f"head {split}"
        )

    return Asset(
        vertices=np.asarray(detail.vertices),
        faces=np.asarray(detail.faces),
        triangles=cfg["head_triangles"],
        views="front",
        colour_fn=None,
        normal_fn=None,
        references=references,
        albedo=HEAD_ALBEDO,
    )


def metaball_asset(cfg: dict) -> Asset:
    """The metaball creature: its marching-cubes mesh for QEM and the baker, the analytic
    colour and normal of the field for the baker, the ray marcher for the references."""
    balls = metaball_creature(cfg["metaball_count"], cfg["seed"])
    margin = float(balls.radii.max()) * 2.5
    lo = balls.centres.min(0).values.numpy() - margin
    hi = balls.centres.max(0).values.numpy() + margin
    vertices, faces = mesh_ops.implicit_mesh(
        lambda p: field(torch.from_numpy(p), balls)[0].numpy(),
        (lo, hi),
        cfg["metaball_grid"],
        1.0,
    )

    def colour_fn(points, face, bary):
        return surface_attributes(torch.from_numpy(points), balls)[0].numpy()

    def normal_fn(points, face, bary):
        return surface_attributes(torch.from_numpy(points), balls)[1].numpy()

    def references(mi: ModuleType, views: list[View], split: str) -> np.ndarray:
        # Held-out references get 4x the sub-pixel rays: their coverage is then close to
        # continuous, like Mitsuba's, and the silhouette metric is not quantised.
        ss = cfg["supersample"] * (2 if split == "test" else 1)
        return np.stack(
            [
                implicit.render_implicit(balls, v, cfg["resolution"], ss, cfg["intensity"])
                for v in views
            ]
        )

    return Asset(
        vertices=vertices,
        faces=faces,
        triangles=cfg["metaball_triangles"],
        views="all_around",
        colour_fn=colour_fn,
        normal_fn=normal_fn,
        references=references,
    )


def triangle_budget(entry: dict, detailed: int, path: str) -> int:
    """A user asset's triangle budget: ``entry["triangles"]``, else ``entry["ratio"]`` of
    the ``detailed`` triangles; refused unless in ``[4, detailed)``."""
    budget = entry["triangles"] or round(entry["ratio"] * detailed)
    how = f"triangles = {budget}" if entry["triangles"] else f"ratio = {entry['ratio']}"
    if not 4 <= budget < detailed:
        raise AssetFileError(
            f"{path}: {how} gives a budget of {budget} triangles; expected at least 4 and "
            f"fewer than the asset's {detailed}"
        )
    return budget


def normalisation(mesh: user_mesh.UserMesh) -> tuple[float, np.ndarray]:
    """Scale and offset that put the bounding box of the used vertices at the origin with a
    half-diagonal of :data:`USER_RADIUS` (``x_stage = (x - offset) * scale``)."""
    used = mesh.vertices[np.unique(mesh.faces)]
    lo, hi = used.min(0), used.max(0)
    return USER_RADIUS / (0.5 * float(np.linalg.norm(hi - lo))), 0.5 * (lo + hi)


def to_asset_matrix(scale: float, offset: np.ndarray) -> np.ndarray:
    """The ``(4, 4)`` inverse of ``x_stage = (x - offset) * scale``."""
    matrix = np.eye(4) / scale
    matrix[:3, 3] = offset
    matrix[3, 3] = 1.0
    return matrix


def user_asset(cfg: dict) -> Asset:
    """A user's asset ``cfg["asset"]`` (``path``, ``ratio`` or ``triangles``, ``views``),
    named ``cfg["case"]``, rendered by Mitsuba from its parts with their own albedo
    (``reference_spp`` for training views, ``test_spp`` for held-out ones)."""
    entry = cfg["asset"]
    source = user_mesh.load(entry["path"])
    scale, offset = normalisation(source)
    mesh = source.transformed(scale, offset)
    budget = triangle_budget(entry, len(mesh.faces), entry["path"])

    def references(mi: ModuleType, views: list[View], split: str) -> np.ndarray:
        spp = cfg["test_spp"] if split == "test" else cfg["reference_spp"]
        seed = reference_seed(cfg["seed"], split)
        return render.render_views(
            mi,
            mesh.mitsuba_shapes(mi),
            views,
            cfg["resolution"],
            spp,
            cfg["intensity"],
            seed,
            f"{cfg['case']} {split}",
        )

    return Asset(
        vertices=mesh.vertices,
        faces=mesh.faces,
        triangles=budget,
        views=entry["views"],
        colour_fn=lambda points, face, bary: mesh.albedo_at(face, bary),
        normal_fn=None,
        references=references,
        to_asset=to_asset_matrix(scale, offset),
        source=mesh,
    )


def load(case: str, cfg: dict) -> Asset:
    """The asset of a use case: one of :data:`neurender.simplification.CASES`, or a user asset
    when ``cfg`` holds its entry under ``asset``; its ``references`` render with the keys
    of ``cfg`` (``resolution``, ``intensity``, ``seed`` and the spp or supersampling)."""
    if "asset" in cfg:
        return user_asset(cfg)
    if case == "head":
        return head_asset(cfg)
    if case == "metaballs":
        return metaball_asset(cfg)
    raise KeyError(f"simplification case {case!r}: expected one of {CASES} or a user asset")
