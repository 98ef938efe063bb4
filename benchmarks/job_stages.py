"""Where the heaviest jobs' time goes, by stage: the profiles of jobs run with
``NEURENDER_PROFILE`` (:mod:`neurender.profiling`) summed into stages, beside each job's
wall time from its Snakemake benchmark file (what the profile does not cover, process
start and the shim's imports, is their difference).

NEURENDER_PROFILE=results/profiles snakemake --cores 2 <targets> --forcerun <rules>
python benchmarks/job_stages.py results results/profiles benchmarks/results/job_stages \\
    --command "NEURENDER_PROFILE=results/profiles snakemake ..."

Writes ``<out>.csv``, tidy: ``rule, job, stage, part_of, seconds`` (the stages of
:func:`neurender.profiling.stage_seconds`, then ``"process start and imports"``: the
benchmark's wall seconds less the profile's total), and ``<out>.json``: the command, the
commit of the checkout the profiles were made in and the machine.
"""

from __future__ import annotations

import argparse
import pstats
import sys
from pathlib import Path

import pandas as pd

from neurender import io
from neurender.profiling import stage_seconds
from neurender.provenance import write_study_sidecar


def job_stages(results: Path, profiles: Path) -> pd.DataFrame:
    """Every profile ``<profiles>/<rule>/<job>.pstats`` by stage; its job's benchmark
    ``<results>/benchmarks/<rule>/<job>.tsv`` adds the process's start when it exists."""
    frames = []
    for path in sorted(profiles.glob("*/*.pstats")):
        rule, job = path.parent.name, path.stem
        stages = stage_seconds(pstats.Stats(str(path)))
        bench = results / "benchmarks" / rule / f"{job}.tsv"
        if bench.is_file():
            wall = float(pd.read_csv(bench, sep="\t").iloc[0]["s"])
            total = float(stages.loc[stages.stage == "total", "seconds"].iloc[0])
            start = pd.DataFrame(
                [("process start and imports", "", max(wall - total, 0.0))],
                columns=stages.columns,
            )
            stages = pd.concat([stages, start], ignore_index=True)
        frames.append(stages.assign(rule=rule, job=job))
    if not frames:
        raise FileNotFoundError(f"no profiles <rule>/<job>.pstats under {profiles}")
    return pd.concat(frames, ignore_index=True)[["rule", "job", "stage", "part_of", "seconds"]]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("results", type=Path, help="the run's results folder")
    parser.add_argument("profiles", type=Path, help="the NEURENDER_PROFILE folder")
    parser.add_argument("out", type=Path, help="output path without suffix")
    parser.add_argument("--command", required=True, help="the command that made the profiles")
    parser.add_argument("--cores", type=int, default=None, help="the cores it was given")
    argv = sys.argv[1:] if argv is None else argv
    args = parser.parse_args(argv)
    table = job_stages(args.results, args.profiles)
    io.write_csv(f"{args.out}.csv", table)
    write_study_sidecar(
        f"{args.out}.json",
        args.command,
        "benchmarks/job_stages.py",
        argv,
        args.results.resolve().parent,
        args.cores,
    )
    print(table.pivot_table(index="stage", columns="job", values="seconds").round(1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
