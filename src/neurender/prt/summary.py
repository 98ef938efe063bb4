"""The DeepPRT tables of the report: data statistics, compression and targets."""

from __future__ import annotations

import math
from pathlib import Path

import pandas as pd

from neurender import equal_quality as shared
from neurender import io, train
from neurender.nn.unet import count_parameters
from neurender.prt import MATERIALS, VARIANTS, int8_name, noise, unseen_scores
from neurender.prt.model import build_network
from neurender.tables import Target, lookup, target_table, threshold, tidy_rows

# Paper section 4.1: 11.8 M parameters, 500 frames, m = 16 (diffuse) or 48 (glossy).
PAPER_WIDTHS = [64, 128, 256, 512]
PAPER_FRAMES = 500
#: The paper form's name in the tables.
PAPER = VARIANTS["paper"]


def data_table(gim_csvs: list[str], manifests: list[str]) -> pd.DataFrame:
    """Per-object geometry-image statistics and per-split ground-truth statistics."""
    frames = [io.read_csv(p) for p in gim_csvs]
    for path in manifests:
        m = io.read_csv(path, ["split", "rays", "seconds"])
        stats = {
            "frames": len(m),
            "directions": m["directions"].iloc[0],
            "seconds_per_frame": m["seconds"].mean(),
            "rays_per_s": m["rays"].sum() / m["seconds"].sum(),
        }
        split = m["split"].iloc[0]
        rows = tidy_rows("prt", Path(path).parent.name, "ray-traced ground truth", split, stats)
        frames.append(pd.DataFrame(rows))
    return pd.concat(frames, ignore_index=True)


def compression_rows(
    objects: list[str],
    checkpoints: dict,
    onnx_files: dict,
    frame_dirs: dict,
    n: int,
    n_bands: int,
) -> pd.DataFrame:
    """Compression ratio r = frames n^2 m / parameters (every variant's, and the paper's
    setting), bytes; ``checkpoints`` and ``onnx_files`` are keyed ``(object, model name,
    material)`` (:data:`neurender.prt.VARIANTS`), a row's model is ``"<model> <material>"``;
    ``frames`` are an object's training and validation frames (``frame_dirs[object]``:
    the train, val and test folders)."""
    k = n_bands * n_bands
    channels = {"diffuse": k, "glossy": 3 * k}
    rows = []

    def add(dataset, model, metric, value):
        rows.extend(tidy_rows("prt", dataset, model, "compression", {metric: value}))

    for material, m in channels.items():
        paper_params = count_parameters(build_network(m, PAPER_WIDTHS, 1))
        for side in (256, 512):
            add(
                f"paper setting {side}^2, {PAPER_FRAMES} frames",
                f"DeepPRT {material}",
                "compression_ratio",
                PAPER_FRAMES * side * side * m / paper_params,
            )
        add("paper setting", f"DeepPRT {material}", "parameters", paper_params)
    for (obj, model, material), checkpoint in checkpoints.items():
        m, label = channels[material], f"{model} {material}"
        frames = sum(len(list(Path(d).glob("*.exr"))) for d in frame_dirs[obj][:2])
        params = train.load_checkpoint(checkpoint)["extra"]["parameters"]
        add(obj, label, "parameters", params)
        add(obj, label, "compression_ratio", frames * n * n * m / params)
        size = Path(onnx_files[(obj, model, material)]).stat().st_size
        add(obj, label, "network_file_bytes", size)
        add(obj, label, "classic_store_float32_bytes", frames * n * n * m * 4)
    for obj in objects:
        exr_bytes = sum(f.stat().st_size for d in frame_dirs[obj] for f in Path(d).glob("*.exr"))
        add(obj, "per-frame EXR (P, N, T, G; float16 transfer)", "bytes_on_disk", exr_bytes)
    return pd.DataFrame(rows)


def shipped_rows(onnx_files: dict, model: str) -> pd.DataFrame:
    """The size of each shipped network file (``onnx_files`` keyed ``(object,
    material)``), a copy of the shipped variant ``model``'s: model ``"<model> <material>
    (shipped)"``, metric ``network_file_bytes``."""
    rows = []
    for (obj, material), path in onnx_files.items():
        size = {"network_file_bytes": Path(path).stat().st_size}
        rows += tidy_rows("prt", obj, f"{model} {material} (shipped)", "compression", size)
    return pd.DataFrame(rows)


def targets(metrics_table: pd.DataFrame, equal: pd.DataFrame, model: str = PAPER) -> list[Target]:
    """Per object and material, of the shipped variant ``model``: test SSIM (and on
    extrapolated frames) at least the target, above MoMoPRT's; where the paper's form
    (``DeepPRT``) was trained too (has rows in the table), the shipped variant's test
    ``rel_l1_radiance`` at most the target fraction of the paper form's (noted where that
    is below the score of an independent ray-traced estimate at the reference's own
    direction count, :func:`neurender.prt.noise.reference_quality_label`); the
    equal-quality speed ratio at least its target, of the float32 graph and of its int8
    graph (the equal-quality table ``equal``: the shared rule's targets,
    :func:`neurender.equal_quality.targets`), and the int8 graph's :func:`int8_targets`."""
    ssim_target = threshold("prt", "ssim")
    versus = threshold("prt", "rel_l1_vs_paper")
    compare = model != PAPER and bool((metrics_table.model == PAPER).any())
    reference_model = noise.reference_quality_label(metrics_table.model.unique())
    rows = []
    for dataset in sorted(metrics_table.dataset.unique()):

        def get(model, split, metric, dataset=dataset):
            return lookup(metrics_table, dataset=dataset, model=model, split=split, metric=metric)

        for material in MATERIALS:
            metric = f"ssim_{material}"
            for split in ("test", "test (extrapolated)"):
                v = get(model, split, metric)
                if not math.isnan(v):
                    check = f"{model} {metric} on {split} >= {ssim_target:g}"
                    rows.append(Target(dataset, check, v, v >= ssim_target))
            deep, lin = get(model, "test", metric), get("MoMoPRT", "test", metric)
            check = f"{model} {metric} on test above MoMoPRT's ({lin:.4f})"
            rows.append(Target(dataset, check, deep, deep > lin))
            if compare:
                metric = f"rel_l1_radiance_{material}"
                ours, paper = get(model, "test", metric), get(PAPER, "test", metric)
                check = f"{model} {metric} on test <= {versus:g} x {PAPER}'s ({paper:.4f})"
                floor = get(reference_model, "test", metric) if reference_model else math.nan
                if versus * paper < floor:
                    check += (
                        f" (below the {floor:.4f} of an independent estimate as good as the"
                        " reference: not measurable against this reference)"
                    )
                rows.append(Target(dataset, check, ours, bool(ours <= versus * paper)))
        rows += int8_targets(metrics_table, dataset, model)
    shipped = equal[equal["model"].isin([model, int8_name(model)])]
    least = threshold("prt", "equal_quality_speedup")
    return rows + shared.targets(shipped, least, "ray-traced transfer")


def int8_targets(metrics_table: pd.DataFrame, dataset: str, model: str) -> list[Target]:
    """The int8 graph's test ``rel_l1_radiance`` (diffuse and glossy) of the variant
    ``model`` on ``dataset`` at most ``int8_rel_l1_ratio`` times the float32 graph's (no
    rows where the table holds no int8 graph)."""
    most = threshold("prt", "int8_rel_l1_ratio")
    rows = []
    for material in MATERIALS:
        metric = f"rel_l1_radiance_{material}"
        ours, float32 = (
            lookup(metrics_table, dataset=dataset, model=m, split="test", metric=metric)
            for m in (int8_name(model), model)
        )
        if math.isnan(ours):
            continue
        check = (
            f"{int8_name(model)} {metric} on test <= {most:g} x the float32 graph's ({float32:.4f})"
        )
        rows.append(Target(dataset, check, ours, bool(ours <= most * float32)))
    return rows


#: The Fig. 6 experiments' test points where the shipped variant must be below MoMoPRT:
#: past the middle of the excluded-expression path, and the extrapolated range of the
#: head-plane blend (the blend weight ``x`` outside the training range [0, 1]).
EXPERIMENT_RANGES = {
    "head_excluded": ("at every point past the middle of the path (x > 0.5)", lambda x: x > 0.5),
    "head_linear": (
        "over the whole extrapolated range (x < 0 or x > 1)",
        lambda x: (x < 0) | (x > 1),
    ),
}


def experiment_targets(table: pd.DataFrame, model: str = PAPER) -> list[Target]:
    """Paper Fig. 6 targets of the shipped variant ``model`` on one experiment's table:
    its L2-RGB below MoMoPRT's on the points of :data:`EXPERIMENT_RANGES` (measured: the
    fraction of those points), and on ``head_excluded`` MoMoPRT's error at the far end at
    least the target multiple of the variant's."""
    rows = []
    for name, (where, points) in EXPERIMENT_RANGES.items():
        sel = table[(table.dataset == name) & (table.metric == "l2rgb_diffuse")]
        if sel.empty:
            continue
        wide = sel.pivot(index="x", columns="model", values="value").sort_index()
        below = (wide[model] < wide["MoMoPRT"])[points(wide.index.to_numpy())]
        check = f"{model} L2-RGB below MoMoPRT's {where}"
        rows.append(Target(name, check, float(below.mean()), bool(below.all())))
        if name == "head_excluded":
            ratio = float(wide["MoMoPRT"].iloc[-1] / wide[model].iloc[-1])
            far = threshold("prt", "excluded_far_ratio")
            check = f"MoMoPRT / {model} L2-RGB at the far end >= {far:g}"
            rows.append(Target(name, check, ratio, ratio >= far))
    return rows


def target_frame(
    metrics_table: pd.DataFrame,
    equal: pd.DataFrame,
    experiments: list[pd.DataFrame],
    model: str = PAPER,
    unseen: pd.DataFrame | None = None,
) -> pd.DataFrame:
    """Every DeepPRT target of the shipped variant ``model`` (:func:`targets` of the
    metrics and the equal-quality table ``equal``,
    :func:`experiment_targets` and, given the unseen-deformation table ``unseen``,
    :func:`neurender.prt.unseen_scores.targets` against the paper form) as one table."""
    rows = targets(metrics_table, equal, model)
    for table in experiments:
        rows += experiment_targets(table, model)
    if unseen is not None:
        rows += unseen_scores.targets(unseen, model, PAPER)
    return target_table("prt", rows)
