"""The simplification stage's timings and targets."""

from __future__ import annotations

import numpy as np
import pandas as pd

from neurender.tables import Target, target_table, threshold


def with_timings(
    stats: pd.DataFrame,
    losses: list[pd.DataFrame],
    evaluate_s: float,
    optimise_threads: int,
    cores: int,
) -> pd.DataFrame:
    """Add each case's optimisation time (sum of its steps) and the stage's total on
    ``cores`` cores (the workflow's, which the evaluation uses), in seconds: this
    evaluation (all cores) plus each job weighted by its share of the cores: the
    one-thread preparations and the optimisation loops (``optimise_threads`` each, the
    config's ``simplification.threads``), which run side by side."""
    extra = [
        {
            "case": loss["case"].iloc[0],
            "quantity": "optimise_seconds",
            "value": loss.loc[loss["metric"] == "seconds", "value"].sum(),
        }
        for loss in losses
    ]
    extra.append({"case": "all", "quantity": "evaluate_seconds", "value": evaluate_s})
    timed = pd.concat([stats, pd.DataFrame(extra)], ignore_index=True)
    seconds = timed["quantity"].str.endswith("_seconds")
    threads = timed["quantity"].map({"optimise_seconds": optimise_threads, "prepare_seconds": 1})
    share = np.minimum(threads.fillna(cores) / cores, 1.0)
    total = {
        "case": "all",
        "quantity": "stage_seconds",
        "value": (timed["value"] * share)[seconds].sum(),
    }
    return pd.concat([timed, pd.DataFrame([total])], ignore_index=True)


def targets(frame: pd.DataFrame, stats: pd.DataFrame) -> pd.DataFrame:
    """Per case: a PSNR gain over QEM, PSNR above the classic bake and a lower coverage
    error than QEM, and where the exports were read back (user assets) the GLB's and the
    OBJ's PSNR within a tolerance of ours; the whole stage within its time
    budget (thresholds from the simplification's ``targets.csv``)."""
    mean = frame.groupby(["dataset", "model", "metric"])["value"].mean()
    minutes = stats.loc[stats["quantity"] == "stage_seconds", "value"].iloc[0] / 60
    budget, gain_db, export_db = (
        threshold("simplification", "stage_minutes"),
        threshold("simplification", "psnr_gain_db"),
        threshold("simplification", "export_tolerance_db"),
    )
    rows = [
        Target(
            "stage",
            f"stage within {budget:g} minutes (measured: minutes)",
            minutes,
            minutes <= budget,
        )
    ]
    for case in frame["dataset"].unique():
        gain = mean[case, "ours", "psnr"] - mean[case, "qem", "psnr"]
        over_baked = mean[case, "ours", "psnr"] - mean[case, "baked", "psnr"]
        cov = (mean[case, "ours", "coverage_error"], mean[case, "qem", "coverage_error"])
        rows += [
            Target(
                case, f"PSNR gain over QEM >= {gain_db:g} dB (measured: dB)", gain, gain >= gain_db
            ),
            Target(
                case,
                "PSNR above the classic baked normal map (measured: ours - baked, dB)",
                over_baked,
                over_baked > 0,
            ),
            Target(
                case,
                "coverage error below QEM's (measured: ours - QEM)",
                cov[0] - cov[1],
                cov[0] < cov[1],
            ),
        ]
        for variant, name in (("ours_glb", "GLB"), ("ours_obj", "OBJ")):
            if (case, variant, "psnr") in mean.index:
                off = abs(mean[case, variant, "psnr"] - mean[case, "ours", "psnr"])
                rows.append(
                    Target(
                        case,
                        f"exported {name} re-renders within {export_db:g} dB of ours "
                        "(measured: |PSNR difference|, dB)",
                        off,
                        off <= export_db,
                    )
                )
    return target_table("simplification", rows)
