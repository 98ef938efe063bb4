"""The simplification's statistics and targets.

The statistics (``results/simplification/stats.csv``, tidy ``case, quantity, value``) are
each case's own (``stats.csv`` of its preparation: the reference's and the simplified
mesh's triangles, the texture size, the preparation's seconds) and its optimisation's
seconds (the sum of its steps' seconds in its loss CSV); every time in them is one a job
measured of itself, none depends on the workflow's core count. The stage's time is a run's
profile (``benchmarks/run_profile.py``), not a statistic nor a target.

The targets read only results (the held-out metrics and the equal-quality table), never a
time, so a run on other cores reruns none of them.
"""

from __future__ import annotations

import pandas as pd

from neurender import equal_quality as shared
from neurender.tables import Target, target_table, threshold

#: What the equal-quality targets' sentences call the classic pipeline
#: (:data:`neurender.simplification.equal_quality.CLASSIC_WORDS`, without its imports).
CLASSIC_WORDS = "classic QEM + bake"


def statistics(stats: list[pd.DataFrame], losses: list[pd.DataFrame]) -> pd.DataFrame:
    """Every case's statistics (its ``stats`` frame: ``case, quantity, value``) followed by
    each case's ``optimise_seconds``, the sum of the ``seconds`` rows of its loss frame
    (``case, step, metric, value``)."""
    optimise = [
        {
            "case": loss["case"].iloc[0],
            "quantity": "optimise_seconds",
            "value": loss.loc[loss["metric"] == "seconds", "value"].sum(),
        }
        for loss in losses
    ]
    return pd.concat([*stats, pd.DataFrame(optimise)], ignore_index=True)


def targets(metrics: pd.DataFrame, equal: pd.DataFrame) -> pd.DataFrame:
    """Per case of the held-out ``metrics`` (columns ``dataset, model, metric, value``): a
    PSNR gain over QEM, PSNR above the classic bake, a lower coverage error than QEM's, the
    shipped GLB's and OBJ's PSNR, read back and rendered, within a tolerance of ours, and
    from the equal-quality table ``equal`` (:mod:`neurender.simplification.equal_quality`)
    the classic QEM + bake needing at least a threshold times ours' triangles to reach its
    quality (:func:`neurender.equal_quality.targets`); thresholds from the
    simplification's ``targets.csv``."""
    mean = metrics.groupby(["dataset", "model", "metric"])["value"].mean()
    gain_db = threshold("simplification", "psnr_gain_db")
    export_db = threshold("simplification", "export_tolerance_db")
    rows = []
    for case in metrics["dataset"].unique():
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
    least = threshold("simplification", "equal_quality_triangle_ratio")
    rows += shared.targets(equal, least, CLASSIC_WORDS, shared.TRIANGLES)
    return target_table("simplification", rows)
