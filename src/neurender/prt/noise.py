"""The ground truth's own noise: training-quality transfer sampled independently.

Train and val targets are Monte Carlo estimates with ``directions`` samples per vertex;
test frames have a clean reference (``reference_directions``). Two more independent
training-quality estimates of test frames show how far the targets themselves are from
the reference (the noise floor): no model trained on them can be scored as exact. One
more independent estimate at the reference's own direction count, scored like a model,
measures the reference's noise: a target below its score is missed even by a ray-traced
estimate as good as the reference itself.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from pathlib import Path

import numpy as np
from tqdm import tqdm

from neurender import metrics
from neurender.prt import frames, transfer
from neurender.prt.scores import Predictions, displayed
from neurender.tables import tidy_rows


def radiance_images(transfer_maps: np.ndarray, light: np.ndarray) -> np.ndarray:
    """Relit diffuse radiance ``(F, 3, n, n)`` of transfer maps ``(F, n, n, K)`` (albedo 1)."""
    rgb = transfer.relight_diffuse(transfer_maps, light)
    return np.moveaxis(rgb, -1, 1)


def noise_floor_rows(
    name: str, positions: np.ndarray, reference_dir: str, light: np.ndarray, cfg: dict, threads
) -> list[dict]:
    """SSIM and L1 of training-quality ground truth against an independent sample and the
    reference, on the first ``noise_floor_frames`` test frames ``positions (F, n, n, 3)``.

    Two independently seeded ground truths with ``directions`` samples are relit (diffuse,
    albedo 1, the stage's light) in geometry-image space, divided by the reference
    radiance's maximum and clamped at 0 (:func:`neurender.prt.scores.displayed`), and
    compared with each other and with the clean reference.
    """
    offset = frames.ray_offset(positions[0], cfg["ray_offset"])
    rows = []
    for f in tqdm(range(min(cfg["noise_floor_frames"], len(positions))), desc=f"{name} noise"):
        ref = frames.read_frame(Path(reference_dir) / f"frame_{f:04d}.exr", cfg["n_bands"])
        samples = [
            transfer.sample_frame(
                positions[f], cfg["directions"], cfg, offset, light, threads, name, "noise", f, t
            )[1:3]
            for t in ("a", "b")
        ]
        imgs = radiance_images(np.stack([samples[0][0], samples[1][0], ref["T"]]), light)
        a, b, r = (displayed(i, float(imgs[2].max())) for i in imgs)
        values = {
            "ssim_sample_vs_sample": metrics.ssim(a, b),
            "ssim_sample_vs_reference": metrics.ssim(a, r),
            "l1_sample_vs_sample": metrics.l1(a, b),
            "l1_sample_vs_reference": metrics.l1(a, r),
            "l1_transfer_vs_reference": float(np.abs(samples[0][0] - ref["T"]).mean()),
            "l1_glossy_vs_reference": float(np.abs(samples[0][1] - ref["G"]).mean()),
        }
        model = ground_truth_label(cfg["directions"])
        rows += tidy_rows("prt", name, model, "test", values, frame=f)
    return rows


def noise_floor_predictions(
    name: str, positions: np.ndarray, light: np.ndarray, cfg: dict, threads: int
) -> Predictions:
    """Ray-traced ground truth of every test frame ``positions (F, n, n, 3)``, sampled
    independently of the reference, as models' predictions ``(F, C, n, n)``: at the
    training quality (``directions``: the noise of the targets models learn from) and at
    the reference's own quality (``reference_directions``: the reference's noise; a target
    below its score is missed even by an estimate as good as the reference)."""
    offset = frames.ray_offset(positions[0], cfg["ray_offset"])
    out = {}
    for key, stream in (("directions", "eval-noise"), ("reference_directions", "eval-ref-noise")):
        diffuse, glossy = [], []
        for f in range(len(positions)):
            _, d, g, _ = transfer.sample_frame(
                positions[f], cfg[key], cfg, offset, light, threads, name, stream, f
            )
            diffuse.append(np.moveaxis(d, -1, 0))
            glossy.append(np.moveaxis(g.reshape(*g.shape[:2], -1), -1, 0))
        label = ground_truth_label(cfg[key])
        out |= {(label, "diffuse"): np.stack(diffuse), (label, "glossy"): np.stack(glossy)}
    return out


def ground_truth_label(directions: int) -> str:
    """The model name of an independent ray-traced estimate with ``directions`` samples."""
    return f"ground truth {directions} dirs"


def reference_quality_label(models: Iterable[str]) -> str | None:
    """Of the models' names, the independent estimate with the most directions (the
    reference's quality: :func:`noise_floor_predictions`); ``None`` if there is none."""
    counts = [int(m.group(1)) for name in models if (m := _GROUND_TRUTH.fullmatch(name))]
    return ground_truth_label(max(counts)) if counts else None


_GROUND_TRUTH = re.compile(r"ground truth (\d+) dirs")
