"""Study (issue 27): the shadowing variant's correction added everywhere or gated by the
disks' occlusion (:class:`neurender.prt.local_model.LocalConfig` ``gated``), side by side.

Two runs of the DeepPRT model stage on the same data (the default config): one as
``results/`` of a whole default run before the gate existed, one with every shadowing
network retrained gated (its ``variants/shadowing_*`` files forced, everything downstream
rerun). This merges their scores into one tidy CSV with a ``correction`` column: the
shipped variant's test and val rows of ``results/prt/metrics.csv`` and every model's and
baseline's rows of ``results/prt/unseen.csv``, plus a sidecar ``.json`` with each run's
folder, command and commit.

Usage::

    python benchmarks/prt_correction_runs.py additive=/run-a/results gated=/run-b/results \\
        --commands "snakemake ..." "snakemake ..." --commits <a> <b>
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import pandas as pd

from neurender import io

OUT = Path("benchmarks/results/prt_correction_runs.csv")
SHIPPED = ("DeepPRT shadowing", "DeepPRT shadowing int8")
METRICS = ("ssim_diffuse", "ssim_glossy", "rel_l1_radiance_diffuse", "rel_l1_radiance_glossy")
COLUMNS = ["correction", "dataset", "model", "split", "family", "strength", "metric", "value"]


def merged(runs: dict[str, Path]) -> pd.DataFrame:
    """Each run's (``runs``: correction -> results folder) shipped-variant test and val
    scores and its unseen-deformation table, with the run's name as ``correction``."""
    frames = []
    for correction, results in runs.items():
        scores = io.read_csv(results / "prt" / "metrics.csv", ["model", "split", "metric"])
        keep = (
            scores.model.isin(SHIPPED)
            & scores.split.isin(["test", "val"])
            & scores.metric.isin(METRICS)
        )
        frames.append(scores[keep].assign(correction=correction))
        unseen = io.read_csv(results / "prt" / "unseen.csv", ["family", "strength"])
        frames.append(unseen.assign(correction=correction))
    return pd.concat(frames, ignore_index=True).reindex(columns=COLUMNS)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("runs", nargs="+", help="correction=results folder")
    parser.add_argument("--commands", nargs="+", required=True, help="each run's command")
    parser.add_argument("--commits", nargs="+", required=True, help="each run's commit")
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args()
    runs = dict(run.split("=", 1) for run in args.runs)
    for name, values in (("--commands", args.commands), ("--commits", args.commits)):
        if len(values) != len(runs):
            parser.error(f"{len(runs)} runs but {len(values)} {name}")
    io.write_csv(args.out, merged({name: Path(folder) for name, folder in runs.items()}))
    sidecar = {
        "note": "DeepPRT model stages on the same default-config data, one correction each",
        "runs": [
            {"correction": name, "results": folder, "command": command, "commit": commit}
            for (name, folder), command, commit in zip(
                runs.items(), args.commands, args.commits, strict=True
            )
        ],
        "merged_by": "python benchmarks/prt_correction_runs.py " + " ".join(sys.argv[1:]),
    }
    with io.atomic_path(args.out.with_suffix(".json")) as tmp_path:
        tmp_path.write_text(json.dumps(sidecar, indent=2) + "\n")


if __name__ == "__main__":
    main()
