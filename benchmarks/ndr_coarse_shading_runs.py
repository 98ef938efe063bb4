"""Study (issue 25): NDR trained on each coarse-shading estimator, side by side.

Runs of the NDR stage on the default config that differ only in the coarse shading
(``ndr.coarse_shading``: ``importance``, the paper's importance-sampled estimator, and
``prefiltered``, the real-time lookups of :mod:`neurender.ndr.prefiltered`, before and
after its bright texels became lights) give one ``results/ndr/metrics.csv`` each; this
merges their quality rows (DSSIM and L2 of the tone-mapped
``I_R``, ``I_D``, ``I_S`` per dataset and model, every network at the config's epochs) into
one tidy CSV with a ``coarse_shading`` column, with NDR's frame times and speed-ups (and
its int8 graph's, model ``ndr_int8``, where the run has it) from each run's
``ndr/equal_quality.csv`` (split ``equal quality``), and a sidecar ``.json`` with
each run's folder, command and commit. Stages that ran side by side do not give fair
timings; each run's equal-quality job was rerun alone on the idle machine
(``--forcerun ndr_equal_quality``) before merging.

Usage, each run from its own clone (``--configfile`` overlays that set the estimator and
the variants)::

    snakemake results/ndr/targets.csv --cores 2 --configfile config/config.yaml imp.yaml
    python benchmarks/ndr_coarse_shading_runs.py \\
        importance=/clone-a/results prefiltered=/clone-b/results \\
        --commands "snakemake ... imp.yaml" "snakemake ... pref.yaml" --commits <a> <b>

``--append`` adds runs to the committed CSV and sidecar, keeping the earlier runs (whose
results folders may be gone) except any of the same name.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import pandas as pd

from neurender import io

OUT = Path("benchmarks/results/ndr_coarse_shading_runs.csv")
QUALITY = ("dssim_I_R", "dssim_I_D", "dssim_I_S", "l2_I_R", "l2_I_D", "l2_I_S", "epochs")
TIMING = (
    "coarse_shading_ms",
    "network_ms",
    "shipped_graph_ms",
    "shipped_int8_graph_ms",
    "ms_per_frame",
    "equal_quality_mitsuba_ms",  # the name in runs before the shared equal-quality rule
    "equal_quality_reference_ms",
    "speedup_vs_training_spp",
    "equal_quality_speedup",
)


def merged(runs: dict[str, Path]) -> pd.DataFrame:
    """The quality rows of each run's ``ndr/metrics.csv`` and NDR's timing rows of its
    ``ndr/equal_quality.csv`` (``runs``: estimator -> results folder) with the estimator
    as column ``coarse_shading``."""
    frames = []
    for shading, results in runs.items():
        path = results / "ndr" / "metrics.csv"
        if not path.is_file():
            raise FileNotFoundError(f"{path}: expected the NDR evaluation of the {shading} run")
        table = pd.read_csv(path)
        frames.append(table[table.metric.isin(QUALITY)].assign(coarse_shading=shading))
        timing = pd.read_csv(results / "ndr" / "equal_quality.csv")
        timing = timing[timing.model.isin(["ndr", "ndr_int8"]) & timing.metric.isin(TIMING)]
        frames.append(timing.assign(coarse_shading=shading))
    columns = ["coarse_shading", "dataset", "model", "split", "metric", "value"]
    return pd.concat(frames, ignore_index=True)[columns]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("runs", nargs="+", help="estimator=results folder")
    parser.add_argument("--commands", nargs="+", required=True, help="each run's command")
    parser.add_argument("--commits", nargs="+", required=True, help="each run's commit")
    parser.add_argument("--out", type=Path, default=OUT)
    parser.add_argument("--changes", nargs="+", help="each run's uncommitted change, '' if none")
    parser.add_argument("--append", action="store_true", help="keep the earlier runs")
    args = parser.parse_args()
    runs = dict(run.split("=", 1) for run in args.runs)
    changes = args.changes or [""] * len(runs)
    for name, values in (
        ("--commands", args.commands),
        ("--commits", args.commits),
        ("--changes", changes),
    ):
        if len(values) != len(runs):
            parser.error(f"{len(runs)} runs but {len(values)} {name}")
    table = merged({shading: Path(folder) for shading, folder in runs.items()})
    new_runs = [
        {"coarse_shading": s, "results": f, "command": c, "commit": k, "dirty": bool(d)}
        | ({"change": d} if d else {})
        for (s, f), c, k, d in zip(runs.items(), args.commands, args.commits, changes, strict=True)
    ]
    merged_by = ["python benchmarks/ndr_coarse_shading_runs.py " + " ".join(sys.argv[1:])]
    if args.append:
        earlier = pd.read_csv(args.out)
        table = pd.concat([earlier[~earlier.coarse_shading.isin(runs)], table], ignore_index=True)
        old = json.loads(args.out.with_suffix(".json").read_text())
        new_runs = [r for r in old["runs"] if r["coarse_shading"] not in runs] + new_runs
        merged_by = old["merged_by"] + merged_by
    io.write_csv(args.out, table)
    sidecar = {
        "note": "NDR stages on the default config, one coarse shading each",
        "runs": new_runs,
        "merged_by": merged_by,
    }
    io.write_json(args.out.with_suffix(".json"), sidecar)


if __name__ == "__main__":
    main()
