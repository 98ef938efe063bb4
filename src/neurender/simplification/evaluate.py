"""Held-out evaluation of the simplified assets (paper 4.1, Figs. 3 and 5).

Every variant is rendered by Mitsuba from the test views (never optimised against), the
same way for all: the atlas mesh with welded (seam-free) vertex normals, shadow rays with
the terminator fix of :mod:`neurender.simplification.terminator`. The renders are compared with
the reference renderer's test images after display encoding
(:func:`neurender.display.srgb`): PSNR (dB), SSIM and FLIP (NVIDIA's ``flip-evaluator``,
LDR mode, lower is better); plus the silhouette coverage error: pixels covered
(alpha >= 0.5) by one image and not the other, as a fraction of the reference's covered
pixels (Fig. 5, top). Variants, at the same triangle count and texture size: ``qem``
(decimated mesh with the reference's material, baked classically where it has colours),
``baked`` (plus a classically baked normal map) and ``ours`` (optimised through Mitsuba).
Also ``ours_glb`` and ``ours_obj``: ours as shipped (the deploy stage's files,
:mod:`neurender.simplification.deploy`) read back
(:func:`neurender.simplification.export.reimport`) and rendered the same way, which checks
what the deploy stage's read-back does not: the textures and the normal map's tangent
frame.
"""

from __future__ import annotations

from types import ModuleType

import flip_evaluator
import numpy as np
import torch

from neurender import io, metrics
from neurender.display import srgb
from neurender.simplification import (
    EXPORTED,
    VARIANTS,
    export,
    formats,
    render,
    terminator,
    views,
)
from neurender.simplification.mesh_ops import LowPolyMesh
from neurender.tables import tidy_rows

#: Every variant is rendered with seed ``seed + EVALUATION_SEED_OFFSET`` (a prime): the
#: same noise for each, independent of the references' (:mod:`neurender.simplification.assets`).
EVALUATION_SEED_OFFSET = 104729


def coverage_error(alpha: np.ndarray, reference_alpha: np.ndarray) -> tuple[float, float]:
    """Fractions of the reference's covered pixels that are covered only by the candidate
    (too much) and only by the reference (missing); ``(H, W)`` coverage images, a pixel
    counting as covered from half coverage on."""
    a, r = alpha >= 0.5, reference_alpha >= 0.5
    n = max(int(r.sum()), 1)
    return float((a & ~r).sum() / n), float((r & ~a).sum() / n)


def image_metrics(image: np.ndarray, reference: np.ndarray) -> dict[str, float]:
    """Metrics of one RGBA render ``(H, W, 4)`` against the reference ``(H, W, 4)``."""
    a, b = srgb(image[..., :3]), srgb(reference[..., :3])
    ta, tb = (torch.from_numpy(x).permute(2, 0, 1)[None].float() for x in (a, b))
    _, flip, _ = flip_evaluator.evaluate(
        b.astype(np.float32), a.astype(np.float32), "LDR", applyMagma=False
    )
    extra, missing = coverage_error(image[..., 3], reference[..., 3])
    return {
        "psnr": float(metrics.psnr(ta, tb)[0]),
        "ssim": float(metrics.ssim(ta, tb)[0]),
        "flip": float(flip),
        "coverage_error": extra + missing,
    }


def render_held_out(mi: ModuleType, dr: ModuleType, shape, test_views: list, cfg: dict, label: str):
    """``shape`` rendered from the held-out ``test_views`` as every variant is (``(N, W, W,
    4)``): ``cfg``'s ``resolution``, ``eval_spp``, ``intensity`` and seed ``seed +``
    :data:`EVALUATION_SEED_OFFSET`, the shadow-terminator integrator."""
    return render.render_views(
        mi,
        shape,
        test_views,
        cfg["resolution"],
        cfg["eval_spp"],
        cfg["intensity"],
        cfg["seed"] + EVALUATION_SEED_OFFSET,
        label,
        terminator.integrator(mi, dr),
    )


def variant_maps(
    variant: str, files: dict
) -> tuple[LowPolyMesh, np.ndarray, np.ndarray | float, np.ndarray | None]:
    """What one variant draws at the shared triangle count and texture size: the atlas
    mesh, its welded positions ``(V, 3)``, its albedo (a ``(T, T, 3)`` map, or for the
    baselines of an asset of uniform albedo that grey, stored with the ``lowpoly`` file)
    and its normal map in Mitsuba's tangent frame (None for ``qem``).

    Args:
        files: the case's ``lowpoly``, ``baked_albedo``, ``baked_normal``, ``mesh``,
            ``normal`` and ``albedo`` files.
    """
    low = formats.load_lowpoly(files["lowpoly"])
    uniform = formats.load_albedo(files["lowpoly"])
    albedo = formats.read_texture(files["baked_albedo"])
    positions, normal_map = low.positions, None
    if variant == "baked":
        normal_map = formats.read_texture(files["baked_normal"])
    elif variant == "ours":
        positions = io.load_npz(files["mesh"])["positions"]
        normal_map = formats.read_texture(files["normal"])
        albedo = formats.read_texture(files["albedo"])
    if uniform is not None and variant != "ours":
        albedo = uniform
    return low, positions, albedo, normal_map


def variant_shape(mi: ModuleType, variant: str, files: dict):
    """The Mitsuba mesh of one variant (:func:`variant_maps`)."""
    low, positions, albedo, normal_map = variant_maps(variant, files)
    return render.atlas_shape(mi, low, render.material(mi, albedo, normal_map), positions)


def exported_shape(mi: ModuleType, path: str, lowpoly: str):
    """The Mitsuba mesh of an exported GLB or OBJ read back into the stage's frame (the
    frame map stored with the case's ``lowpoly`` file)."""
    low, albedo, normal_map = export.reimport(path, formats.load_to_asset(lowpoly))
    return render.atlas_shape(mi, low, render.material(mi, albedo, normal_map))


def evaluate_case(
    mi: ModuleType,
    dr: ModuleType,
    case: str,
    files: dict,
    cfg: dict,
    exports: dict | None = None,
) -> tuple[list[dict], tuple[np.ndarray, dict[str, np.ndarray]]]:
    """Render every variant of one case from its test views (and the ``exports``, the
    ``glb`` and ``obj`` files of :data:`EXPORTED`, when given) with ``cfg``'s
    ``resolution``, ``eval_spp``, ``intensity`` and ``seed``.

    Returns:
        tidy rows (one per view and metric) and, for the comparison figure, the reference
        and every variant's render of the most side-on view (the head in profile).
    """
    test_views = views.views_from_frame(io.read_csv(files["test_views"]))
    references = formats.read_images(files["test_images"])
    rows, renders = [], {}
    for variant in VARIANTS + (tuple(EXPORTED) if exports else ()):
        shape = (
            exported_shape(mi, exports[EXPORTED[variant]], files["lowpoly"])
            if variant in EXPORTED
            else variant_shape(mi, variant, files)
        )
        renders[variant] = render_held_out(mi, dr, shape, test_views, cfg, f"{case} {variant}")
        for i, (image, ref) in enumerate(zip(renders[variant], references, strict=True)):
            rows += tidy_rows(
                "simplification", case, variant, "test", image_metrics(image, ref), view=i
            )
    pick = int(np.argmax([abs(v.azimuth) if case == "head" else 0 for v in test_views]))
    return rows, (references[pick], {v: renders[v][pick] for v in VARIANTS})
