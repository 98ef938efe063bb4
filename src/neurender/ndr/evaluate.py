"""NDR scores on the held-out test splits (paper Tables 1 and 2).

Test sets: ``complex`` and ``diffuse`` (paper Tables 1 and 2) and ``sunlit`` (ours: complex
objects under real-world-like outdoor maps, whose sun holds most of the power in one
texel of the coarse map; rows labelled ``real-world-like maps``).

Every method is scored against the clean test references (``reference_spp``) on
Reinhard tone-mapped images (``x / (1 + x)``, as the networks see them) within the eroded
mask: ``l2`` (mean squared error) and ``dssim`` ((1 - SSIM) / 2) of ``I_R`` and, where the
method produces them, ``I_D`` and ``I_S``. Rows ``noise floor`` score an independent render
at the training sample count against the same reference: differences below it cannot be
resolved by these test sets. Every network runs in eval mode (batch norm with running
statistics; pix2pix here trains at batch 16, and per-image statistics scored worse).
"""

from __future__ import annotations

import dataclasses

import torch

from neurender import metrics, train
from neurender.display import reinhard
from neurender.ndr import DATASETS, TRAINED_ON
from neurender.ndr.buffers import NDRDataset
from neurender.ndr.model import SHADING_INPUT, NDRModel, compose, load_model, shading_input
from neurender.ndr.variants import VARIANTS
from neurender.nn.unet import count_parameters
from neurender.tables import tidy_rows

NOISE_FLOOR = "noise floor"
IMAGES = ("I_R", "I_D", "I_S")


@torch.no_grad()
def predict(model: NDRModel, dataset, device: torch.device, batch_size: int = 16):
    """HDR predictions ``{I_D, I_S, I_R}`` ``(N, 3, H, W)`` for a whole split (CPU tensors)."""
    outputs: dict[str, list] = {}
    for start in range(0, len(dataset), batch_size):
        items = [dataset[i] for i in range(start, min(start + batch_size, len(dataset)))]
        batch = {k: torch.stack([it[k] for it in items]).to(device) for k in items[0]}
        for key, value in model(batch).items():
            outputs.setdefault(key, []).append(value.cpu())
    return {k: torch.cat(v) for k, v in outputs.items()}


def score(
    pred: dict[str, torch.Tensor], truth: dict[str, torch.Tensor], mask: torch.Tensor
) -> dict[str, torch.Tensor]:
    """Per-sample ``l2_<image>`` and ``dssim_<image>`` ``(N,)`` on tone-mapped images."""
    out = {}
    for name in IMAGES:
        if name not in pred:
            continue
        a, b = reinhard(pred[name]) * mask, reinhard(truth[name]) * mask
        out[f"l2_{name}"] = metrics.l2(a, b, mask)
        out[f"dssim_{name}"] = metrics.dssim(a, b, mask)
    return out


def reported(method: str, kind: str, values: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
    """The scores that mean something for ``method`` on ``kind`` data: only ``I_R`` for a
    variant that predicts it directly; ``I_R`` and ``I_D`` on diffuse data (``I_S`` is zero
    there, and ``I_R = I_D * A_D``)."""
    direct = method in VARIANTS and "I_R" in VARIANTS[method].targets
    if not (direct or kind == "diffuse"):
        return values
    keep = ("I_R",) if direct else ("I_R", "I_D")
    return {k: v for k, v in values.items() if k.endswith(keep)}


@dataclasses.dataclass
class SplitScores:
    """One test split scored: tidy ``rows`` (means and each network's budget),
    ``per_sample`` rows and what the comparison figure shows (``truth``, ``buffers`` and
    every method's predictions, HDR ``(N, 3, H, W)``)."""

    rows: list[dict]
    per_sample: list[dict]
    truth: dict[str, torch.Tensor]
    buffers: dict[str, torch.Tensor]
    methods: dict[str, dict[str, torch.Tensor]]


def budget(name: str, kind: str, checkpoint: str, model: NDRModel) -> list[dict]:
    """A network's training budget beside its errors: epochs trained (equal for every
    variant, ``ndr_model.epochs``) and parameters."""
    values = {
        "epochs": float(train.epochs_trained(checkpoint)),
        "parameters": float(count_parameters(model.net)),
    }
    return tidy_rows("ndr", DATASETS[kind], name, "test", values)


def _sample_rows(kind: str, name: str, values: dict[str, torch.Tensor]) -> list[dict]:
    return [
        {"dataset": DATASETS[kind], "model": name, "sample": i, "metric": metric, "value": float(x)}
        for metric, v in values.items()
        for i, x in enumerate(v)
    ]


def score_split(
    kind: str, data: NDRDataset, checkpoints: dict[str, str], device: torch.device
) -> SplitScores:
    """Score the noise floor, the shading input and every checkpoint (variant name ->
    file) trained on the data of ``kind`` (:data:`neurender.ndr.TRAINED_ON`: the sunlit
    test set is rendered by the networks trained on complex data) against the test split
    ``data``; rows are labelled with the kind's :data:`neurender.ndr.DATASETS` name."""
    b = data.buffers
    truth = compose(b["I_D"], b["I_S"], b)
    methods = {
        NOISE_FLOOR: compose(b["I_D_noisy"], b["I_S_noisy"], b),
        SHADING_INPUT: shading_input(b),
    }
    budgets = []
    for name, path in checkpoints.items():
        if VARIANTS[name].data == TRAINED_ON[kind]:
            model = load_model(path, device)
            methods[name] = predict(model, data, device)
            if TRAINED_ON[kind] == kind:  # the budget once, beside the training data's scores
                budgets += budget(name, kind, path, model)
    rows, per_sample = [], []
    for name, pred in methods.items():
        values = reported(name, kind, score(pred, truth, b["mask"]))
        means = {k: v.mean() for k, v in values.items()}
        rows += tidy_rows("ndr", DATASETS[kind], name, "test", means)
        per_sample += _sample_rows(kind, name, values)
    return SplitScores(rows + budgets, per_sample, truth, b, methods)
