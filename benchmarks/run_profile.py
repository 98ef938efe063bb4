"""Where a run's time goes: every job's wall and CPU seconds and peak memory, from the
``benchmark:`` files Snakemake wrote under ``<results>/benchmarks/<rule>/``, each job under
its rule and its stage as ``python -m neurender.plan`` counts them; with the whole run's
wall clock, CPU time and peak memory from ``/usr/bin/time -v`` when its report is given.

/usr/bin/time -v -o run.time snakemake --cores 2 results/report.html
python benchmarks/run_profile.py results benchmarks/results/default_run_profile \\
    --time run.time --command "snakemake --cores 2 results/report.html"

Writes ``<out>.csv``, tidy: ``rule, stage, job, metric, value`` with the metrics
``wall_s``, ``cpu_s`` (user + system seconds of the job's processes) and ``max_rss_mb``,
one row per job and metric; ``<out>_stages.csv``: per stage its jobs, their summed wall
and CPU minutes and largest peak memory (:func:`by_stage`); and ``<out>.json``: the run's
command, the commit of the checkout the results lie in, the machine and, from the time
report, ``wall_min``, ``cpu_min`` and ``max_rss_mb`` of the whole run.
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

import pandas as pd

from neurender import io, methods
from neurender.provenance import write_study_sidecar

#: The lines of ``/usr/bin/time -v``'s report this reads, by the name they are given here.
TIME_FIELDS = {
    "user_s": "User time (seconds)",
    "system_s": "System time (seconds)",
    "wall": "Elapsed (wall clock) time (h:mm:ss or m:ss)",
    "max_rss_kb": "Maximum resident set size (kbytes)",
}


def job_rows(results: Path) -> pd.DataFrame:
    """One row per job and metric (``wall_s``, ``cpu_s``, ``max_rss_mb``) from the
    Snakemake benchmark files ``results/benchmarks/<rule>/<job>.tsv`` (the job: the path
    below the rule's folder, without ``.tsv``); columns ``rule, stage, job, metric,
    value``, ordered by rule and job."""
    rows = []
    for path in sorted((results / "benchmarks").glob("*/**/*.tsv")):
        rule = path.relative_to(results / "benchmarks").parts[0]
        job = str(path.relative_to(results / "benchmarks" / rule).with_suffix(""))
        first = pd.read_csv(path, sep="\t").iloc[0]
        values = {"wall_s": first["s"], "cpu_s": first["cpu_time"], "max_rss_mb": first["max_rss"]}
        stage = methods.rule(rule).stage
        rows += [(rule, stage, job, metric, float(v)) for metric, v in values.items()]
    if not rows:
        raise FileNotFoundError(f"no benchmark files under {results / 'benchmarks'}")
    return pd.DataFrame(rows, columns=["rule", "stage", "job", "metric", "value"])


def seconds(clock: str) -> float:
    """``h:mm:ss`` or ``m:ss`` (fractional seconds allowed) in seconds."""
    total = 0.0
    for part in clock.split(":"):
        total = total * 60 + float(part)
    return total


def whole_run(time_report: str) -> dict[str, float]:
    """``wall_min``, ``cpu_min`` (user + system) and ``max_rss_mb`` of the process that
    ``/usr/bin/time -v`` reported on (its text ``time_report``); peak memory is the
    largest single process's, not the sum over the jobs.

    Raises:
        ValueError: naming the line the report lacks.
    """
    found = {}
    for name, label in TIME_FIELDS.items():
        match = re.search(rf"^\s*{re.escape(label)}: (\S+)$", time_report, re.MULTILINE)
        if match is None:
            raise ValueError(f"the time report has no line '{label}' (from /usr/bin/time -v)")
        found[name] = match.group(1)
    return {
        "wall_min": seconds(found["wall"]) / 60,
        "cpu_min": (float(found["user_s"]) + float(found["system_s"])) / 60,
        "max_rss_mb": float(found["max_rss_kb"]) / 1024,
    }


def by_stage(rows: pd.DataFrame) -> pd.DataFrame:
    """Per stage: jobs' summed wall and CPU minutes and their largest peak memory, the
    stages by summed wall time, largest first."""
    wide = rows.pivot_table(index=["stage", "rule", "job"], columns="metric", values="value")
    table = wide.groupby("stage").agg(
        jobs=("wall_s", "size"),
        wall_min=("wall_s", lambda s: s.sum() / 60),
        cpu_min=("cpu_s", lambda s: s.sum() / 60),
        max_rss_mb=("max_rss_mb", "max"),
    )
    return table.sort_values("wall_min", ascending=False)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("results", type=Path, help="a finished run's results folder")
    parser.add_argument("out", help="output path without suffix (.csv and .json are added)")
    parser.add_argument("--time", type=Path, help="/usr/bin/time -v's report on the run")
    parser.add_argument("--command", default="", help="the command the run was started with")
    parser.add_argument("--cores", type=int, default=None, help="the cores it was given")
    argv = sys.argv[1:] if argv is None else argv
    args = parser.parse_args(argv)

    rows = job_rows(args.results)
    io.write_csv(f"{args.out}.csv", rows)
    io.write_csv(f"{args.out}_stages.csv", by_stage(rows).reset_index())
    extra = {} if args.time is None else {"whole_run": whole_run(args.time.read_text())}
    write_study_sidecar(
        f"{args.out}.json",
        args.command,
        "benchmarks/run_profile.py",
        argv,
        args.results.resolve().parent,
        args.cores,
        **extra,
    )
    print(by_stage(rows).round(1).to_string())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
