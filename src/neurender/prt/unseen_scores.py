"""The unseen-deformation benchmark: frames of the families of
:mod:`neurender.prt.unseen`, their clean ground truth, every model's and baseline's
predictions scored, and its targets.

* Frames: per family and strength, ``frames`` deformations of the mean training shape
  (indices ``0 .. frames - 1``; a family's frames at growing strength are the same
  deformation, growing). ``extrapolation`` frames also have shape parameters (the mean
  training blendshape weights plus :func:`neurender.prt.unseen.extrapolation_step`), so
  a model on blendshape weights (MoMoPRT on the head) can predict them.
* Ground truth: ray-traced transfer (:func:`neurender.prt.transfer.sample_frame`) at the
  clean reference's direction count, seeded by ``(object, "unseen_<family>_<strength>",
  frame, directions)``, ray offset from the mean shape.
* Baselines that need no learning: ``unshadowed``, the transfer where nothing occludes
  (diffuse and glossy, from the frame's normals; exact on a surface that cannot shadow
  itself), and ``static``, the ray-traced transfer of the mean training shape (classic
  PRT of one pose), the same for every frame.
* Scores per frame and material: SSIM of the rendered images (:mod:`neurender.prt.scores`,
  the camera framing the frame) and the relative L1 of per-vertex radiance under the
  light, ``sum |R_pred - R_gt| / sum |R_gt|`` over vertices and RGB
  (:func:`neurender.prt.scores.relative_l1`; the test frames' score is over the rendered
  images instead).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd

from neurender.prt import render, scores, transfer, unseen
from neurender.prt.frames import Split
from neurender.tables import Target, threshold, tidy_rows

#: Names of the baselines in the tables.
UNSHADOWED, STATIC, DISKS = "unshadowed", "static", "disk occlusion"
#: The ``split`` of the benchmark's rows.
SPLIT = "unseen"


@dataclasses.dataclass
class Case:
    """The frames of one family at one strength.

    Attributes:
        positions: ``(F, n, n, 3)`` float64 geometry images.
        params: ``(F, P)`` shape parameters (blendshape weights), or ``None`` where the
            deformation has none (every family but ``extrapolation``).
    """

    family: str
    strength: float
    positions: np.ndarray
    params: np.ndarray | None = None

    @property
    def tag(self) -> str:
        """The ground truth's seed part (and the benchmark script's)."""
        return f"unseen_{self.family}_{self.strength}"


def cases(
    mean: np.ndarray,
    families: tuple[str, ...],
    strengths: list[float],
    frames: int,
    seed: int,
    deltas: np.ndarray,
    mean_params: np.ndarray | None = None,
) -> list[Case]:
    """Every family's frames at every strength (:func:`neurender.prt.unseen.deform`).

    Args:
        mean: ``(n, n, 3)`` mean training shape.
        deltas: ``(K, n, n, 3)`` blendshape displacements (``extrapolation`` only).
        mean_params: ``(K,)`` mean training blendshape weights: the ``extrapolation``
            frames' shape parameters are these plus their step (``None``: no parameters).
    """
    out = []
    for family in families:
        for strength in strengths:
            positions = np.stack(
                [unseen.deform(mean, family, strength, seed, i, deltas) for i in range(frames)]
            )
            params = None
            if family == "extrapolation" and mean_params is not None:
                k = len(deltas)
                steps = np.stack(
                    [unseen.extrapolation_step(strength, seed, i, k) for i in range(frames)]
                )
                params = np.asarray(mean_params, np.float64)[None] + steps
            out.append(Case(family, float(strength), positions, params))
    return out


def traced(
    positions: np.ndarray,
    directions: int,
    cfg: dict,
    offset: float,
    light: np.ndarray | None,
    threads: int,
    name: str,
    tag: str,
    params: np.ndarray | None = None,
) -> Split:
    """A split of frames ``(F, n, n, 3)`` with their ray-traced transfer (``cfg``: ``seed``,
    ``direction_sets``, ``n_bands``); glossy under SH ``light`` ``(K, 3)``, zeros if it is
    ``None``; ``params`` ``(F, P)`` or none (``(F, 0)``)."""
    normals, diffuse, glossy = [], [], []
    for f, p in enumerate(positions):
        nrm, d, g, _ = transfer.sample_frame(
            p, directions, cfg, offset, light, threads, name, tag, f, directions
        )
        normals.append(nrm)
        diffuse.append(d)
        glossy.append(np.zeros((*d.shape[:2], 3, d.shape[-1]), np.float32) if g is None else g)
    return Split(
        np.asarray(positions, np.float32),
        np.stack(normals).astype(np.float32),
        np.stack(diffuse).astype(np.float32),
        np.stack(glossy).astype(np.float32),
        np.zeros((len(positions), 0), np.float32) if params is None else params.astype(np.float32),
    )


def baselines(
    data: Split, mean: Split, n_bands: int, glossy_coeffs: np.ndarray, light: np.ndarray
) -> dict:
    """``(model, material) -> (F, C, n, n)``: the baselines that need no learning, for
    every frame of ``data``: unshadowed, static and the disks' occlusion estimate
    (``mean``: the mean training shape's one-frame split; ``glossy_coeffs``:
    :func:`neurender.prt.unshadowed.glossy_polynomial` of the SH ``light`` ``(K, 3)``)."""
    frames = len(data.positions)
    return {
        (DISKS, "diffuse"): unseen.disk_occlusion_baseline(data.positions, n_bands),
        (DISKS, "glossy"): unseen.disk_occlusion_glossy_baseline(
            data.positions, glossy_coeffs, light
        ),
        (UNSHADOWED, "diffuse"): unseen.unshadowed_baseline(data.positions, n_bands),
        (UNSHADOWED, "glossy"): unseen.unshadowed_glossy_baseline(data.positions, glossy_coeffs),
        (STATIC, "diffuse"): unseen.static_baseline(mean.targets("diffuse")[0], frames),
        (STATIC, "glossy"): unseen.static_baseline(mean.targets("glossy")[0], frames),
    }


def frame_scores(
    data: Split, predictions: scores.Predictions, light: np.ndarray, cfg: dict
) -> dict[str, dict[str, np.ndarray]]:
    """``model -> metric -> (F,)`` per-frame ``ssim_<material>`` and
    ``rel_l1_radiance_<material>`` of every ``(model, material)`` prediction ``(F, C, n,
    n)`` against ``data``'s transfer (``cfg``: ``render_resolution``, ``glossy_exponent``)."""
    out: dict[str, dict[str, list[float]]] = {}
    for f, positions in enumerate(data.positions):
        raster = render.Raster(positions, cfg["render_resolution"])
        mask = raster.mask_image()
        for (model, material), pred in predictions.items():
            gt, pr = (
                scores.radiance(material, c, positions, light, raster.eye, cfg["glossy_exponent"])
                for c in (data.targets(material)[f], pred[f])
            )
            ssim = scores.image_ssim(raster.shade(gt), raster.shade(pr), mask)
            metrics = out.setdefault(model, {})
            metrics.setdefault(f"ssim_{material}", []).append(ssim)
            metrics.setdefault(f"rel_l1_radiance_{material}", []).append(scores.relative_l1(pr, gt))
    return {m: {k: np.array(v) for k, v in metrics.items()} for m, metrics in out.items()}


def case_rows(name: str, case: Case, values: dict[str, dict[str, np.ndarray]]) -> list[dict]:
    """Tidy rows (split ``unseen``, keys ``family`` and ``strength``) of one case's
    :func:`frame_scores`, each the mean over its frames."""
    rows = []
    for model, metrics in values.items():
        means = {k: float(np.mean(v)) for k, v in metrics.items()}
        rows += tidy_rows(
            "prt", name, model, SPLIT, means, family=case.family, strength=case.strength
        )
    return rows


def targets(table: pd.DataFrame, shipped: str, paper: str | None = None) -> list[Target]:
    """The unseen-deformation targets per object and material, on the relative L1
    of radiance of a table of :func:`case_rows`:

    * the ``shipped`` model below both baselines on every family, averaged over its
      strengths and at its strongest (measured: the worst family's ratio of the shipped
      model's error to the better baseline's; threshold ``unseen_baseline_ratio``);
    * never more than ``unseen_strength_ratio`` times the better baseline at any strength;
    * below the ``paper`` model on average over every family and strength (threshold
      ``unseen_paper_ratio``; skipped without one, or if it is the shipped model).
    """
    below = threshold("prt", "unseen_baseline_ratio")
    at_most = threshold("prt", "unseen_strength_ratio")
    paper_ratio = threshold("prt", "unseen_paper_ratio")
    rows = []
    for dataset in sorted(table.dataset.unique()):
        for material in ("diffuse", "glossy"):
            metric = f"rel_l1_radiance_{material}"
            sel = table[(table.dataset == dataset) & (table.metric == metric)]
            if sel.empty or shipped not in set(sel.model):
                continue
            wide = sel.pivot_table(index=["family", "strength"], columns="model", values="value")
            base = wide[[UNSHADOWED, STATIC]]
            means = wide.groupby(level="family").mean()
            mean_ratio = means[shipped] / means[[UNSHADOWED, STATIC]].min(axis=1)
            top = wide.groupby(level="family").tail(1).droplevel("strength")
            top_ratio = top[shipped] / top[[UNSHADOWED, STATIC]].min(axis=1)
            ratio = wide[shipped] / base.min(axis=1)
            summaries = {"averaged over strengths": mean_ratio, "at the strongest": top_ratio}
            for where, worst in summaries.items():
                family = worst.idxmax()
                check = (
                    f"{shipped} {metric} {where} / the better baseline's < {below:g} on every "
                    f"unseen family (worst: {family})"
                )
                rows.append(Target(dataset, check, float(worst.max()), bool(worst.max() < below)))
            family, strength = ratio.idxmax()
            check = (
                f"{shipped} {metric} / the better baseline's <= {at_most:g} at every unseen "
                f"strength (worst: {family} at {strength:g})"
            )
            rows.append(Target(dataset, check, float(ratio.max()), bool(ratio.max() <= at_most)))
            if paper and paper != shipped and paper in wide:
                value = float(wide[shipped].mean() / wide[paper].mean())
                check = (
                    f"{shipped} / {paper} {metric}, mean over unseen families and strengths "
                    f"< {paper_ratio:g}"
                )
                rows.append(Target(dataset, check, value, value < paper_ratio))
    return rows
