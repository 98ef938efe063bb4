"""The DeepPRT tables of the report: data statistics, compression and targets."""

from __future__ import annotations

import math
from pathlib import Path

import pandas as pd

from neurender import io, train
from neurender.nn.unet import count_parameters
from neurender.prt import MATERIALS
from neurender.prt.model import build_network
from neurender.tables import Target, lookup, target_table, threshold, tidy_rows

# Paper section 4.1: 11.8 M parameters, 500 frames, m = 16 (diffuse) or 48 (glossy).
PAPER_WIDTHS = [64, 128, 256, 512]
PAPER_FRAMES = 500


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
    """Compression ratio r = frames n^2 m / parameters (ours and the paper's setting), bytes;
    ``frames`` are an object's training and validation frames (``frame_dirs[object]``: the
    train, val and test folders)."""
    k = n_bands * n_bands
    rows = []

    def add(dataset, model, metric, value):
        rows.extend(tidy_rows("prt", dataset, model, "compression", {metric: value}))

    for material, m in (("diffuse", k), ("glossy", 3 * k)):
        paper_params = count_parameters(build_network(m, PAPER_WIDTHS, 1))
        for side in (256, 512):
            add(
                f"paper setting {side}^2, {PAPER_FRAMES} frames",
                f"DeepPRT {material}",
                "compression_ratio",
                PAPER_FRAMES * side * side * m / paper_params,
            )
        add("paper setting", f"DeepPRT {material}", "parameters", paper_params)
        for obj in objects:
            frames = sum(len(list(Path(d).glob("*.exr"))) for d in frame_dirs[obj][:2])
            params = train.load_checkpoint(checkpoints[(obj, material)])["extra"]["parameters"]
            add(obj, f"DeepPRT {material}", "parameters", params)
            add(obj, f"DeepPRT {material}", "compression_ratio", frames * n * n * m / params)
            add(
                obj,
                f"DeepPRT {material}",
                "network_file_bytes",
                Path(onnx_files[(obj, material)]).stat().st_size,
            )
            add(obj, f"DeepPRT {material}", "classic_store_float32_bytes", frames * n * n * m * 4)
    for obj in objects:
        exr_bytes = sum(f.stat().st_size for d in frame_dirs[obj] for f in Path(d).glob("*.exr"))
        add(obj, "per-frame EXR (P, N, T, G; float16 transfer)", "bytes_on_disk", exr_bytes)
    return pd.DataFrame(rows)


def targets(metrics_table: pd.DataFrame) -> list[Target]:
    """Per object and material: test SSIM (and on extrapolated frames) at least the target,
    above MoMoPRT's; the equal-quality speed ratio at least its target."""
    ssim_target = threshold("prt", "ssim")
    speed_target = threshold("prt", "equal_quality_speedup")
    rows = []
    for dataset in sorted(metrics_table.dataset.unique()):

        def get(model, split, metric, dataset=dataset):
            return lookup(metrics_table, dataset=dataset, model=model, split=split, metric=metric)

        for material in MATERIALS:
            metric = f"ssim_{material}"
            for split in ("test", "test (extrapolated)"):
                v = get("DeepPRT", split, metric)
                if not math.isnan(v):
                    check = f"DeepPRT {metric} on {split} >= {ssim_target:g}"
                    rows.append(Target(dataset, check, v, v >= ssim_target))
            deep, lin = get("DeepPRT", "test", metric), get("MoMoPRT", "test", metric)
            check = f"DeepPRT {metric} on test above MoMoPRT's ({lin:.4f})"
            rows.append(Target(dataset, check, deep, deep > lin))
        v = get("DeepPRT", "timing", "equal_quality_speedup")
        check = f"equal-quality speed ratio >= {speed_target:g}x"
        rows.append(Target(dataset, check, v, bool(v >= speed_target)))
    return rows


def experiment_targets(table: pd.DataFrame) -> list[Target]:
    """Excluded-expression targets (paper Fig. 6): DeepPRT below MoMoPRT everywhere, and
    MoMoPRT's error at the far end at least the target multiple of DeepPRT's."""
    sel = table[(table.dataset == "head_excluded") & (table.metric == "l2rgb_diffuse")]
    if sel.empty:
        return []
    wide = sel.pivot(index="x", columns="model", values="value").sort_index()
    ratio = float(wide["MoMoPRT"].iloc[-1] / wide["DeepPRT"].iloc[-1])
    below = wide["DeepPRT"] < wide["MoMoPRT"]
    far = threshold("prt", "excluded_far_ratio")
    return [
        Target(
            "head_excluded",
            "DeepPRT L2-RGB below MoMoPRT's at every test point",
            float(below.mean()),
            bool(below.all()),
        ),
        Target(
            "head_excluded",
            f"MoMoPRT / DeepPRT L2-RGB at the far end >= {far:g}",
            ratio,
            ratio >= far,
        ),
    ]


def target_frame(metrics_table: pd.DataFrame, experiments: list[pd.DataFrame]) -> pd.DataFrame:
    """Every DeepPRT target (:func:`targets` and :func:`experiment_targets`) as one table."""
    rows = targets(metrics_table)
    for table in experiments:
        rows += experiment_targets(table)
    return target_table("prt", rows)
