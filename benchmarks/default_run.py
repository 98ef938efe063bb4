"""A run's results kept as a committed study: every method's headline numbers (its report
summary's rows) and targets, with the command and commit that made them, so that the
README and the method pages quote a file rather than a run nobody can open.

/usr/bin/time -v -o run.time snakemake --cores 2 results/report.html
python benchmarks/default_run.py results benchmarks/results/default_run \\
    --command "snakemake --cores 2 results/report.html"

Writes ``<out>_headlines.csv`` (``method, label, ours, paper, source``: the report's
headline rows, :func:`neurender.report.build.headline_values`), ``<out>_targets.csv``
(every method's ``targets.csv``: ``method, subject, check, measured, met``), a copy of
every table the report shows under ``<out>/`` (``<out>/<method>/metrics.csv`` for
``results/<method>/metrics.csv``; a few hundred kB) and ``<out>.json``: the command,
its config files, the commit of the checkout the results lie in and the machine. Time and
memory of the same run: ``benchmarks/run_profile.py``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import pandas as pd

from neurender import io, methods
from neurender.plan import load_config
from neurender.provenance import write_study_sidecar
from neurender.report.build import headline_values, table_name


def report_tables(results: Path, configfiles: list[str]) -> dict[str, list[Path]]:
    """Each method's report tables that lie under ``results`` (the report's list for the
    config of ``configfiles``), by method key."""
    cfg = load_config(configfiles)
    return {
        method.key: [
            results.parent / t
            for t in method.report_inputs(cfg).tables
            if (results.parent / t).is_file()
        ]
        for method in methods.METHODS
    }


def run_tables(found: dict[str, list[Path]], results: Path) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The headline rows and the targets of every method with report tables in ``found``
    (:func:`report_tables` of ``results``)."""
    headlines, targets = [], []
    for method in methods.METHODS:
        files = found[method.key]
        tables = {table_name(f, method.key): io.read_csv(f) for f in files}
        if not tables:
            continue
        headlines.append(headline_values(method, tables))
        if "targets" in tables:
            targets.append(tables["targets"])
    if not headlines:
        raise FileNotFoundError(f"no method's tables under {results}")
    empty = pd.DataFrame(columns=["method", "subject", "check", "measured", "met"])
    return pd.concat(headlines, ignore_index=True), pd.concat(targets or [empty])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("results", type=Path, help="the run's results folder")
    parser.add_argument("out", type=Path, help="output path without suffix")
    parser.add_argument("--command", required=True, help="the command that made the run")
    parser.add_argument("--configfile", nargs="*", default=[], help="the run's --configfile")
    parser.add_argument("--cores", type=int, default=None, help="the cores it was given")
    argv = sys.argv[1:] if argv is None else argv
    args = parser.parse_args(argv)
    found = report_tables(args.results, args.configfile)
    headlines, targets = run_tables(found, args.results)
    io.write_csv(f"{args.out}_headlines.csv", headlines)
    io.write_csv(f"{args.out}_targets.csv", targets)
    for files in found.values():
        for f in files:
            io.copy_file(f, args.out / f.relative_to(args.results))
    write_study_sidecar(
        f"{args.out}.json",
        args.command,
        "benchmarks/default_run.py",
        argv,
        args.results.resolve().parent,
        args.cores,
        configfiles=["config/config.yaml", *args.configfile],
    )
    met = targets["met"].astype(str).str.lower() == "true"
    print(f"{len(headlines)} headline rows; targets met {int(met.sum())} of {len(targets)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
