"""Appearance-driven optimisation of a low-poly mesh and its textures (paper 3, 5.3).

Each step renders the latent mesh with Mitsuba's ``direct_projective`` integrator (correct
silhouette gradients; with the shadow-terminator fix of :mod:`neurender.simplification.terminator`,
as the evaluation renders it) from one training view, compares it with the reference image of that
view through the L1 loss on ``sRGB(log(x + 1))`` (eq. 4) and adds the uniform Laplacian
regulariser ``mean |delta_i - delta'_i|^2`` (eq. 5) with the decaying weight of eq. 6;
Adam updates the welded vertex positions, the normal map and (optionally) the albedo map.
Vertex normals are recomputed from the positions every step, differentiably (Mitsuba does
not do it when positions change).
"""

from __future__ import annotations

import dataclasses
import math
import time
from types import ModuleType

import numpy as np
import pandas as pd
from tqdm import tqdm

from neurender.simplification import terminator
from neurender.simplification.mesh_ops import LowPolyMesh
from neurender.simplification.render import atlas_shape, material, scene_dict, set_view
from neurender.simplification.views import View

NORMAL_KEY = "shape.bsdf.normalmap.data"
ALBEDO_KEY = "shape.bsdf.nested_bsdf.reflectance.data"
PAPER_DECAY_K = 1e-6  # eq. 6, for the paper's 10k steps
PAPER_STEPS = 10_000
MIN_NORMAL_Z = 0.1


@dataclasses.dataclass(frozen=True, kw_only=True)
class OptimiseConfig:
    """Steps of ``batch`` views, samples per pixel, learning rates (positions in scene units
    per step) that decay exponentially to ``lr_final_fraction`` of their start, the eq. 6
    Laplacian weights, and what is optimised. The values and their defaults are the
    ``simplification`` config's (the schema); only what is optimised is the code's choice."""

    steps: int
    batch: int
    spp: int
    width: int
    lr_positions: float
    lr_textures: float
    lr_final_fraction: float
    laplacian_scale: float
    laplacian_min_fraction: float
    intensity: float
    seed: int
    optimise_positions: bool = True
    optimise_albedo: bool = False

    @classmethod
    def from_stage(cls, cfg: dict, **overrides) -> OptimiseConfig:
        """The optimiser's keys of the ``simplification`` config (``resolution`` is the width),
        plus overrides; a missing key is named."""
        fields = {f.name: f for f in dataclasses.fields(cls)}
        names = set(fields) - {"width"}
        required = {n for n in names if fields[n].default is dataclasses.MISSING}
        missing = sorted(required - set(cfg) - set(overrides)) + (
            [] if "resolution" in cfg else ["resolution"]
        )
        if missing:
            raise KeyError(f"the optimisation's config lacks the simplification keys {missing}")
        return cls(
            width=cfg["resolution"], **{k: v for k, v in cfg.items() if k in names}, **overrides
        )


@dataclasses.dataclass(frozen=True)
class Start:
    """What the optimisation starts from: the QEM atlas mesh, its normal map ``(T, T, 3)``
    in Mitsuba's tangent frame (values in [0, 1]) and its albedo, a linear grey or a
    ``(T, T, 3)`` map (optimised only when ``OptimiseConfig.optimise_albedo``)."""

    low: LowPolyMesh
    normal_map: np.ndarray
    albedo: float | np.ndarray


@dataclasses.dataclass(frozen=True)
class References:
    """The training views and their reference renders ``(N, W, W, >=3)``, linear RGB."""

    views: list[View]
    images: np.ndarray

    def __post_init__(self):
        if len(self.images) != len(self.views):
            raise ValueError(f"{len(self.images)} reference images for {len(self.views)} views")


def laplacian_decay(steps: int) -> float:
    """The eq. 6 rate ``k``, rescaled so ``lambda_t`` has the shape it has over the paper's
    10k steps (``prod 10^-kt`` depends on ``k t^2``) over ``steps`` steps."""
    return PAPER_DECAY_K * (PAPER_STEPS / steps) ** 2


def tonemap(dr: ModuleType, x):
    """Paper eq. 4: the sRGB transfer function of ``log(x + 1)``, for ``x >= 0``."""
    y = dr.log(dr.maximum(x, 0.0) + 1.0)
    return dr.select(y <= 0.0031308, 12.92 * y, 1.055 * dr.power(y, 1 / 2.4) - 0.055)


def scalar(x) -> float:
    """A one-element Dr.Jit array or tensor as a Python float."""
    return float(np.asarray(x).ravel()[0])


def neighbour_pairs(faces: np.ndarray, n_vertices: int) -> tuple[np.ndarray, np.ndarray]:
    """Directed one-ring pairs ``(i, j)`` and the valence ``(V,)`` of each vertex."""
    edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    edges = np.unique(np.sort(edges, 1), axis=0)
    pairs = np.concatenate([edges, edges[:, ::-1]])
    return pairs, np.bincount(pairs[:, 0], minlength=n_vertices)


class LatentMesh:
    """The optimised representation and its differentiable mapping into Mitsuba's scene."""

    def __init__(self, mi: ModuleType, dr: ModuleType, low: LowPolyMesh):
        self.mi, self.dr, self.n = mi, dr, len(low.positions)
        self.corners = [
            mi.UInt32(np.ascontiguousarray(low.faces[:, k], np.uint32)) for k in range(3)
        ]
        self.vmap = mi.UInt32(np.ascontiguousarray(low.vmap, np.uint32))
        pairs, valence = neighbour_pairs(low.faces, self.n)
        self.pair_i, self.pair_j = (
            mi.UInt32(np.ascontiguousarray(pairs[:, k], np.uint32)) for k in range(2)
        )
        self.inv_valence = mi.Float(1.0 / np.maximum(valence, 1))

    def scatter_sum(self, values, index, kind):
        """Sum of 3-vectors ``values`` per target vertex ``index`` (differentiable)."""
        dr, mi = self.dr, self.mi
        out = []
        for c in range(3):
            acc = dr.zeros(mi.Float, self.n)
            dr.scatter_add(acc, values[c], index)
            out.append(acc)
        return kind(*out)

    def points(self, flat):
        return self.dr.unravel(self.mi.Point3f, flat)

    def normals(self, p):
        """Area-weighted unit vertex normals of welded points ``p``."""
        dr, mi = self.dr, self.mi
        a, b, c = (dr.gather(mi.Point3f, p, idx) for idx in self.corners)
        face_n = dr.cross(b - a, c - a)
        n = sum(self.scatter_sum(face_n, idx, mi.Vector3f) for idx in self.corners)
        return dr.normalize(n)

    def laplacian(self, p):
        """Uniform differentials ``delta_i = v_i - mean of its one ring``."""
        dr, mi = self.dr, self.mi
        ring = self.scatter_sum(dr.gather(mi.Point3f, p, self.pair_j), self.pair_i, mi.Vector3f)
        return p - ring * self.inv_valence

    def write(self, params, p) -> None:
        """Atlas positions and normals of welded points ``p`` into the scene parameters."""
        dr, mi = self.dr, self.mi
        params["shape.vertex_positions"] = dr.ravel(dr.gather(mi.Point3f, p, self.vmap))
        params["shape.vertex_normals"] = dr.ravel(
            dr.gather(mi.Vector3f, self.normals(p), self.vmap)
        )


@dataclasses.dataclass(kw_only=True)
class _Run:
    """What the steps of one optimisation share: the Mitsuba scene and its parameters, the
    latent mesh, both optimisers, the Laplacian of the start mesh, the training views and
    their reference images, the order the views are drawn in, the normal map's lower
    bound, and the Laplacian weight of eq. 6 (set at step 0) with its decay rate."""

    scene: object
    params: object
    latent: LatentMesh
    tex_opt: object
    pos_opt: object
    delta0: object
    views: list[View]
    targets: list
    order: np.ndarray
    normal_lo: object
    decay: float
    lam: float | None = None
    lam_min: float | None = None


def _start(
    mi: ModuleType, dr: ModuleType, start: Start, references: References, cfg: OptimiseConfig
) -> _Run:
    """The scene of the start mesh with its textures, and the optimisers over them."""
    low, normal_map = start.low, start.normal_map
    shape = atlas_shape(mi, low, material(mi, start.albedo, normal_map))
    scene = mi.load_dict(
        scene_dict(
            mi,
            shape,
            references.views[0],
            cfg.width,
            cfg.spp,
            cfg.intensity,
            terminator.integrator(mi, dr, cfg.spp),
            alpha=False,
            sample_border=True,
        )
    )
    params = mi.traverse(scene)
    latent = LatentMesh(mi, dr, low)
    tex_keys = [NORMAL_KEY] + ([ALBEDO_KEY] if cfg.optimise_albedo else [])
    tex_opt = mi.ad.Adam(lr=cfg.lr_textures, params={k: params[k] for k in tex_keys})
    pos_opt = mi.ad.Adam(
        lr=cfg.lr_positions, params={"positions": mi.Float(np.ravel(low.positions))}
    )
    delta0 = dr.detach(latent.laplacian(latent.points(mi.Float(np.ravel(low.positions)))))
    targets = [mi.TensorXf(np.ascontiguousarray(r[..., :3])) for r in references.images]
    draws = cfg.steps * cfg.batch
    views = np.arange(len(references.views))
    order = np.random.default_rng(cfg.seed).permutation(np.resize(views, draws))
    # Tangent-space normals stay in the upper hemisphere (z >= MIN_NORMAL_Z), as in nvdiffrec.
    normal_lo = mi.TensorXf(
        np.broadcast_to([0.0, 0.0, (1 + MIN_NORMAL_Z) / 2], normal_map.shape)
        .astype(np.float32)
        .copy()
    )
    return _Run(
        scene=scene,
        params=params,
        latent=latent,
        tex_opt=tex_opt,
        pos_opt=pos_opt,
        delta0=delta0,
        views=references.views,
        targets=targets,
        order=order,
        normal_lo=normal_lo,
        decay=laplacian_decay(cfg.steps),
    )


def _batch_gradients(
    mi: ModuleType, dr: ModuleType, run: _Run, step: int, cfg: OptimiseConfig
) -> tuple[list[float], float]:
    """Render and back-propagate every view of ``step``'s batch (the Laplacian term with
    the first); the image L1 of each view and the Laplacian term's value."""
    image_losses = []
    laplacian_value = math.nan
    for item in range(cfg.batch):
        draw = step * cfg.batch + item
        # Mitsuba differentiates a render against the scene as it is at backward time,
        # so each view of a batch is rendered and back-propagated on its own; the
        # gradients add up in the optimisers' variables.
        run.params.update(run.tex_opt)
        p = run.latent.points(run.pos_opt["positions"])
        run.latent.write(run.params, p)
        set_view(mi, run.params, run.views[run.order[draw]])
        run.params.update()
        image = mi.render(run.scene, run.params, seed=cfg.seed + draw, spp=cfg.spp)
        loss_image = dr.mean(
            dr.abs(tonemap(dr, image) - tonemap(dr, run.targets[run.order[draw]])), axis=None
        )
        image_losses.append(scalar(loss_image))
        loss = loss_image / cfg.batch
        if item == 0:
            loss_lap = dr.mean(dr.squared_norm(run.latent.laplacian(p) - run.delta0), axis=None)
            if run.lam is None:
                # delta - delta0 is 0 at the start, so the weight is set against the
                # absolute Laplacian of the initial mesh (lambda_0 = 0.25 L_image / L_delta).
                absolute = scalar(dr.mean(dr.squared_norm(run.delta0), axis=None))
                run.lam = cfg.laplacian_scale * image_losses[0] / max(absolute, 1e-12)
                run.lam_min = cfg.laplacian_min_fraction * run.lam
            run.lam = (run.lam - run.lam_min) * 10 ** (-run.decay * step) + run.lam_min
            laplacian_value = scalar(loss_lap)
            loss = loss + run.lam * loss_lap
        dr.backward(loss)
    return image_losses, laplacian_value


def _apply(dr: ModuleType, run: _Run, cfg: OptimiseConfig) -> None:
    """One Adam step of what is optimised, textures clipped to their valid range."""
    run.tex_opt.step()
    if cfg.optimise_positions:
        run.pos_opt.step()
    run.tex_opt[NORMAL_KEY] = dr.clip(run.tex_opt[NORMAL_KEY], run.normal_lo, 1.0)
    if cfg.optimise_albedo:
        run.tex_opt[ALBEDO_KEY] = dr.clip(run.tex_opt[ALBEDO_KEY], 0.0, 1.0)


def optimise(
    mi: ModuleType, dr: ModuleType, start: Start, references: References, cfg: OptimiseConfig
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, pd.DataFrame]:
    """Optimise the ``start`` mesh and textures against the training ``references``.

    Returns:
        welded positions ``(V, 3)``, normal map ``(T, T, 3)``, albedo map ``(T, T, 3)``
        (None unless optimised) and a tidy loss table (``step, metric, value``).
    """
    run = _start(mi, dr, start, references, cfg)
    rows = []
    for step in tqdm(range(cfg.steps), desc="optimise", mininterval=10):
        started = time.perf_counter()
        lr_scale = cfg.lr_final_fraction ** (step / max(cfg.steps - 1, 1))
        run.tex_opt.set_learning_rate(cfg.lr_textures * lr_scale)
        run.pos_opt.set_learning_rate(
            cfg.lr_positions * lr_scale if cfg.optimise_positions else 0.0
        )
        image_losses, laplacian_value = _batch_gradients(mi, dr, run, step, cfg)
        _apply(dr, run, cfg)
        image_l1 = float(np.mean(image_losses))
        if not math.isfinite(image_l1):
            raise FloatingPointError(f"image loss is not finite at step {step}")
        elapsed = time.perf_counter() - started
        for metric, value in (
            ("image_l1", image_l1),
            ("laplacian", laplacian_value),
            ("lambda", run.lam),
            ("seconds", elapsed),
        ):
            rows.append({"step": step, "metric": metric, "value": value})
    positions = np.array(run.pos_opt["positions"]).reshape(-1, 3).astype(np.float64)
    normal_out = np.array(run.tex_opt[NORMAL_KEY])
    albedo_out = np.array(run.tex_opt[ALBEDO_KEY]) if cfg.optimise_albedo else None
    return positions, normal_out, albedo_out, pd.DataFrame(rows)
