"""What the NDR stage made and what it cost: split statistics, timings and the targets.

Tables are tidy (:mod:`neurender.tables`); times are wall-clock seconds unless named
otherwise. Target thresholds come from NDR's ``targets.csv`` (beside this module).
"""

from __future__ import annotations

import pandas as pd
import torch

from neurender import equal_quality as shared
from neurender import io
from neurender.ndr import equal_quality as eq
from neurender.ndr import split_kind
from neurender.ndr.buffers import NDRDataset
from neurender.ndr.evaluate import NOISE_FLOOR
from neurender.ndr.model import SHADING_INPUT, NDRModel
from neurender.ndr.variants import VARIANTS
from neurender.tables import Target, lookup, target_table, threshold, tidy_rows
from neurender.timing import timed

#: Manifest columns the timing table reads (seconds on one core, see ``data.make_sample``).
TIMING_COLUMNS = ["render_seconds", "train_spp_render_seconds", "coarse_seconds", "spp"]
#: Manifests written before ``ndr.coarse_shading`` existed had the importance estimator.
DEFAULT_SHADING = "importance"


def split_statistics(manifests: dict[str, str]) -> pd.DataFrame:
    """Tidy rows per split (name -> manifest CSV): sample count and the means of the
    manifest's numeric columns."""
    rows = []
    for split, path in manifests.items():
        frame = io.read_csv(path, ["sample", "primitives", "coverage", "spp", "seconds"])
        kind, part = split_kind(split)
        values = {"samples": len(frame), **frame.drop(columns="sample").mean(numeric_only=True)}
        rows += tidy_rows("ndr", kind, "data", part, values)
    return pd.DataFrame(rows)


@torch.no_grad()
def network_seconds(
    model: NDRModel, data: NDRDataset, device: torch.device, repeats: int = 20
) -> float:
    """Median seconds of one forward pass at batch 1 (test sample 0) on ``device``, after
    three uncounted calls that warm up allocators and kernels."""
    batch = {key: v[None].to(device) for key, v in data[0].items()}
    return timed(model, batch, repeats=repeats, warmup=3)[1]


def timing_table(network: float, train_manifest: str, test_manifest: str, where: str):
    """Seconds per image (medians): the network (``network`` s, measured ``where``) with
    and without coarse shading, beside Mitsuba's ground truth at the training and the test
    sample counts (both maps, one CPU core) as measured while making the data, and the
    coarse shading's preparation of a map's lighting (once per map) where the manifest
    has it. Rows name the coarse-shading estimator of the training data (column
    ``coarse_shading``, the manifest's)."""
    made = io.read_csv(train_manifest, TIMING_COLUMNS)
    tested = io.read_csv(test_manifest, TIMING_COLUMNS)
    coarse = float(made.coarse_seconds.median())
    values = {
        "network_seconds": network,
        "coarse_shading_seconds": coarse,
        "network_with_coarse_shading_seconds": network + coarse,
        f"ground_truth_seconds_{int(made.spp.iloc[0])}spp": float(made.render_seconds.median()),
        f"ground_truth_seconds_{int(tested.spp.iloc[0])}spp": float(tested.render_seconds.median()),
    }
    values["speedup_vs_training_spp_render"] = (
        float(made.render_seconds.median()) / values["network_with_coarse_shading_seconds"]
    )
    if "coarse_lighting_seconds" in made:  # once per map, not per image
        values["coarse_lighting_seconds_per_map"] = float(made.coarse_lighting_seconds.median())
    shading = made.get("coarse_shading", pd.Series([DEFAULT_SHADING])).iloc[0]
    return pd.DataFrame(
        tidy_rows("ndr", "complex", "ndr", f"timing ({where})", values, coarse_shading=shading)
    )


def _beats(ndr: float, name: str, other: float) -> Target:
    return Target(
        name, f"NDR's DSSIM(I_R) below {name}'s ({other:.4f}) (measured: NDR's)", ndr, ndr < other
    )


def speed_targets(equal: pd.DataFrame) -> list[Target]:
    """Each NDR graph of the equal-quality table (``equal_quality.csv``, :mod:`neurender.ndr.
    equal_quality`; NDR, and its int8 graph where the table has it) end to end against
    Mitsuba: at the training spp, and at equal DSSIM of ``I_R`` (the shared rule's targets,
    :func:`neurender.equal_quality.targets`)."""
    rows = []
    for model, suffix in ((eq.NETWORK, ""), (eq.NETWORK_INT8, " (int8 graph)")):
        graph = equal[(equal["model"] == model) & (equal["split"] == eq.SPLIT)]
        if graph.empty:
            continue
        what = eq.GRAPH_LABELS[model]
        value = graph.set_index("metric")["value"]
        spp = int(value["training_spp"])
        least = threshold("ndr", "training_spp_speedup")
        ratio = float(value["speedup_vs_training_spp"])
        rows.append(
            Target(
                f"Mitsuba at the training {spp} spp{suffix}",
                f"{what} end to end (coarse shading + network) at least {least:g}x faster "
                "(measured: ratio)",
                ratio,
                ratio >= least,
            )
        )
    least = threshold("ndr", "equal_quality_speedup")
    return rows + shared.targets(equal[equal["split"] == eq.SPLIT], least, "Mitsuba render")


def int8_targets(equal: pd.DataFrame) -> list[Target]:
    """The int8 graph's DSSIM of ``I_R`` on each whole test split at most
    ``int8_dssim_ratio`` times the float32 graph's (``equal_quality.csv``, split
    :data:`neurender.ndr.equal_quality.GRAPH_SPLIT`)."""
    scores = equal[(equal["split"] == eq.GRAPH_SPLIT) & (equal["metric"] == eq.METRIC)]
    most = threshold("ndr", "int8_dssim_ratio")
    rows = []
    for dataset, part in scores.groupby("dataset", sort=False):
        value = part.set_index("model")["value"]
        ratio = float(value[eq.NETWORK_INT8] / value[eq.NETWORK])
        rows.append(
            Target(
                f"int8 graph ({dataset})",
                f"DSSIM(I_R) of the int8 graph at most {most:g} x the float32 graph's "
                f"({value[eq.NETWORK]:.4f}) (measured: ratio)",
                ratio,
                ratio <= most,
            )
        )
    return rows


def targets(metrics: pd.DataFrame, equal: pd.DataFrame) -> pd.DataFrame:
    """The default config's targets on the complex test data (NDR against the shading
    input, every ablation and baseline that ran, and the noise floor; ``metrics``, the
    evaluation's table), NDR against Real Shading on the diffuse data, NDR's speed against
    Mitsuba (:func:`speed_targets` of ``equal``, the equal-quality table) and the int8
    graph's quality (:func:`int8_targets`), each stated as met or missed."""

    def dssim(model: str, dataset: str = "complex") -> float:
        return lookup(metrics, model=model, metric="dssim_I_R", dataset=dataset)

    ndr, base = dssim("ndr"), dssim(SHADING_INPUT)
    gain, ratio = threshold("ndr", "shading_input_gain"), threshold("ndr", "no_intrinsic_ratio")
    rows = [
        Target(
            "ndr",
            f"DSSIM(I_R) at least {gain:.0%} below the shading input's ({base:.4f}) "
            "(measured: fraction below)",
            1 - ndr / base,
            ndr <= (1 - gain) * base,
        )
    ]
    others = [n for n, v in VARIANTS.items() if v.data == "complex" and n != "ndr"]
    scores = {n: dssim(n) for n in others}
    rows += [_beats(ndr, n, other) for n, other in scores.items() if other == other]
    intrinsic = dssim("no_intrinsic")
    if intrinsic == intrinsic:
        rows.append(
            Target(
                "no_intrinsic",
                f"clearly worse than NDR: DSSIM(I_R) at least {ratio:g} x NDR's (measured: ratio)",
                intrinsic / ndr,
                intrinsic >= ratio * ndr,
            )
        )
    floor = dssim(NOISE_FLOOR)
    rows.append(
        Target(
            NOISE_FLOOR,
            f"reference noise floor ({floor:.4f}) below NDR's DSSIM(I_R) (measured: floor / NDR's)",
            floor / ndr,
            floor < ndr,
        )
    )
    diffuse_ndr, real = dssim("ndr_diffuse", "diffuse"), dssim("real_shading", "diffuse")
    if diffuse_ndr == diffuse_ndr and real == real:
        rows.append(
            Target(
                "real_shading",
                f"diffuse/fixed: NDR's DSSIM(I_R) below Real Shading's ({real:.4f}) "
                "(measured: NDR's)",
                diffuse_ndr,
                diffuse_ndr < real,
            )
        )
    rows += speed_targets(equal) + int8_targets(equal)
    return target_table("ndr", rows)
