"""Studies (issue 27): runs of the DeepPRT model stage on the same data, side by side.

Each run is the ``results/`` of the default config with only the shadowing networks
retrained one way (their ``variants/shadowing_*`` files, everything downstream rerun).
This merges their scores into one tidy CSV with a column naming the run (``--column``):
the shipped variant's test and val rows of ``results/prt/metrics.csv`` and every model's
and baseline's rows of ``results/prt/unseen.csv``, plus a sidecar ``.json`` with each
run's folder, command and commit. Two studies so far:

* ``correction`` (the default; ``benchmarks/results/prt_correction_runs.csv``): the
  correction added everywhere or gated by the disks' occlusion
  (:class:`neurender.prt.local_model.LocalConfig` ``gated``);
* ``batch`` (``benchmarks/results/prt_batch_runs.csv``): the variant's batch size and
  learning rate (config keys ``prt_model.shadowing_batch_size`` and ``shadowing_lr``).

Usage::

    python benchmarks/prt_correction_runs.py additive=/run-a/results gated=/run-b/results \\
        --commands "snakemake ..." "snakemake ..." --commits <a> <b>
    python benchmarks/prt_correction_runs.py --column batch --out \\
        benchmarks/results/prt_batch_runs.csv "5, lr 2e-3=/run-a/results" ...
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import pandas as pd

from neurender import io

OUT = Path("benchmarks/results/prt_correction_runs.csv")
NOTE = "DeepPRT model stages on the same default-config data, one correction each"
SHIPPED = ("DeepPRT shadowing", "DeepPRT shadowing int8")
METRICS = ("ssim_diffuse", "ssim_glossy", "rel_l1_radiance_diffuse", "rel_l1_radiance_glossy")
COLUMNS = ["dataset", "model", "split", "family", "strength", "metric", "value"]


def merged(runs: dict[str, Path], column: str = "correction") -> pd.DataFrame:
    """Each run's (``runs``: name -> results folder) shipped-variant test and val scores
    and its unseen-deformation table, with the run's name in ``column``."""
    frames = []
    for name, results in runs.items():
        scores = io.read_csv(results / "prt" / "metrics.csv", ["model", "split", "metric"])
        keep = (
            scores.model.isin(SHIPPED)
            & scores.split.isin(["test", "val"])
            & scores.metric.isin(METRICS)
        )
        frames.append(scores[keep].assign(**{column: name}))
        unseen = io.read_csv(results / "prt" / "unseen.csv", ["family", "strength"])
        frames.append(unseen.assign(**{column: name}))
    return pd.concat(frames, ignore_index=True).reindex(columns=[column, *COLUMNS])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("runs", nargs="+", help="name=results folder")
    parser.add_argument("--column", default="correction", help="the column naming the run")
    parser.add_argument("--note", default=NOTE, help="what the runs compare (the sidecar's)")
    parser.add_argument("--commands", nargs="+", required=True, help="each run's command")
    parser.add_argument("--commits", nargs="+", required=True, help="each run's commit")
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args()
    runs = dict(run.split("=", 1) for run in args.runs)
    for name, values in (("--commands", args.commands), ("--commits", args.commits)):
        if len(values) != len(runs):
            parser.error(f"{len(runs)} runs but {len(values)} {name}")
    io.write_csv(
        args.out, merged({name: Path(folder) for name, folder in runs.items()}, args.column)
    )
    sidecar = {
        "note": args.note,
        "runs": [
            {args.column: name, "results": folder, "command": command, "commit": commit}
            for (name, folder), command, commit in zip(
                runs.items(), args.commands, args.commits, strict=True
            )
        ],
        "merged_by": "python benchmarks/prt_correction_runs.py " + " ".join(sys.argv[1:]),
    }
    io.write_json(args.out.with_suffix(".json"), sidecar)


if __name__ == "__main__":
    main()
