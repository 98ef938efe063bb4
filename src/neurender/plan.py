"""How long and how much memory a config needs, per stage, before anything runs.

    python -m neurender.plan --configfile config/paper.yaml        # estimate
    python -m neurender.plan --configfile config/smoke.yaml --check results
    python -m neurender.plan --calibrate results:config/smoke.yaml other_results:config/config.yaml
    python -m neurender.plan --configfile config/paper.yaml --limits 2880 256000

The jobs are the ones ``snakemake -n`` would run for ``results/report.html`` under the
config (so user assets and variants count as they will run); each job's cost comes from
:mod:`neurender.costs`. Core-hours are estimated seconds times the job's threads; GPU-hours
use the training rates that ``benchmarks/gpu_check.sh`` measured on a GPU
(``benchmarks/results/gpu_check_*.csv``), where there are any. ``--check`` compares the
estimates with a finished run's ``benchmark:`` files and fails beyond a stated factor;
``--calibrate`` fits ``costs.csv`` to the benchmark files of finished runs; ``--limits``
fails when a job would ask the scheduler for more time (minutes) or memory (MB) than a
partition allows.
"""

from __future__ import annotations

import argparse
import dataclasses
import glob
import re
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from neurender import config, costs, io

ROOT = Path(__file__).resolve().parents[2]
#: The factor within which ``--check`` accepts a stage's estimate (docs/cluster.md).
CHECK_FACTOR = 3.0
#: Seconds within which ``--check`` accepts a stage's estimate whatever the ratio: a stage
#: of a job or two of a few seconds is timing noise (a loaded machine triples it), and the
#: scheduler's resources round every job up to whole minutes.
CHECK_SLACK_S = 10.0
#: The columns of ``costs.csv``, one row per rule.
FIT_COLUMNS = ("rule", "fixed_s", "per_unit_s", "fixed_mb", "per_unit_mb", "samples")


@dataclasses.dataclass(frozen=True)
class PlannedJob:
    rule: str
    wildcards: dict[str, str]
    threads: int
    benchmark: str


def load_config(configfiles: Sequence[str]) -> dict:
    """The config the workflow sees: ``config/config.yaml`` updated by ``configfiles``
    in order, with the schema's defaults filled in."""
    from snakemake.utils import update_config, validate

    cfg = io.read_yaml(ROOT / "config/config.yaml")
    for path in configfiles:
        update_config(cfg, io.read_yaml(path))
    config.check_renamed(cfg, [ROOT / "config/config.yaml", *configfiles])
    config.check_names_are_text(cfg)
    validate(cfg, str(ROOT / "workflow/schemas/config.schema.yaml"))
    return cfg


def dag_jobs(configfiles: Sequence[str], workdir: Path = ROOT) -> list[PlannedJob]:
    """Every job of the config's DAG, from ``snakemake -n --forceall``'s listing."""
    command = [
        sys.executable,
        "-m",
        "snakemake",
        "results/report.html",
        "-n",
        "--forceall",
        "--cores",
        "2",
    ]
    if configfiles:  # after the target: --configfile takes every argument that follows
        command += ["--configfile", *map(str, configfiles)]
    out = subprocess.run(command, cwd=workdir, capture_output=True, text=True, check=False)
    if out.returncode:
        raise RuntimeError(f"snakemake -n failed:\n{out.stderr[-3000:]}")
    jobs = []
    for block in re.split(r"\n(?:local)?rule ", out.stdout)[1:]:
        rule = block.split(":", 1)[0].strip()
        fields = dict(re.findall(r"^\s+(\w+): (.*)$", block, re.M))
        wildcards = dict(
            pair.split("=", 1) for pair in fields.get("wildcards", "").split(", ") if "=" in pair
        )
        jobs.append(
            PlannedJob(rule, wildcards, int(fields.get("threads", 1)), fields.get("benchmark", ""))
        )
    return jobs


def gpu_seconds_per_unit(pattern: str = "benchmarks/results/gpu_check_*.csv") -> dict[str, float]:
    """Rule -> GPU seconds per work unit, from the newest GPU check's training rates."""
    files = sorted(glob.glob(str(ROOT / pattern)))
    if not files:
        return {}
    table = io.read_csv(files[-1], ["device", "rule", "seconds_per_step", "units_per_step"])
    gpu = table[table.device.str.startswith("cuda")]
    return dict(zip(gpu.rule, gpu.seconds_per_step / gpu.units_per_step, strict=True))


def estimates(cfg: dict, jobs: list[PlannedJob]) -> pd.DataFrame:
    """One row per job: stage, rule, estimated seconds, core-seconds, GPU seconds, MB."""
    per_unit = gpu_seconds_per_unit() if cfg.get("gpus", 0) else {}
    rows = []
    for job in jobs:
        e = costs.estimate(job.rule, cfg, job.wildcards)
        gpu = per_unit.get(job.rule)
        rows.append(
            {
                "stage": costs.stage(job.rule),
                "rule": job.rule,
                "wildcards": ",".join(f"{k}={v}" for k, v in job.wildcards.items()),
                "benchmark": job.benchmark,
                "runtime_min": e.runtime_min,
                "mem_limit_mb": e.mem_limit_mb,
                "seconds": e.seconds,
                "core_seconds": e.seconds * job.threads,
                "gpu_seconds": costs.work(job.rule, cfg, job.wildcards)[0] * gpu if gpu else 0.0,
                "mem_mb": e.mem_mb,
            }
        )
    return pd.DataFrame(rows)


def summary(table: pd.DataFrame) -> pd.DataFrame:
    """Per stage: jobs, core-hours, GPU-hours and the largest job's memory in GB."""
    grouped = table.groupby("stage", sort=False)
    out = pd.DataFrame(
        {
            "jobs": grouped.size(),
            "core_hours": grouped.core_seconds.sum() / 3600,
            "gpu_hours": grouped.gpu_seconds.sum() / 3600,
            "peak_memory_gb": grouped.mem_mb.max() / 1024,
        }
    )
    out.loc["whole DAG"] = [
        len(table),
        table.core_seconds.sum() / 3600,
        table.gpu_seconds.sum() / 3600,
        table.mem_mb.max() / 1024,
    ]
    return out


def beyond_limits(table: pd.DataFrame, minutes: float, mem_mb: float) -> pd.DataFrame:
    """The jobs whose scheduler request (``runtime``, ``mem_mb``) exceeds a partition's
    limits."""
    over = (table.runtime_min > minutes) | (table.mem_limit_mb > mem_mb)
    return table.loc[over, ["rule", "wildcards", "runtime_min", "mem_limit_mb"]]


def measured_seconds(results: Path, table: pd.DataFrame) -> pd.Series:
    """Each job's measured wall seconds from its ``benchmark:`` file under ``results``'s
    parent (NaN where missing)."""
    base = results.parent
    values = []
    for path in table.benchmark:
        file = base / path
        values.append(float(pd.read_csv(file, sep="\t")["s"].iloc[0]) if file.is_file() else np.nan)
    return pd.Series(values, index=table.index)


def check(
    table: pd.DataFrame,
    results: Path,
    factor: float = CHECK_FACTOR,
    slack_s: float = CHECK_SLACK_S,
) -> pd.DataFrame:
    """Per stage: estimated and measured job seconds and their ratio, flagged beyond
    ``factor`` unless the two are within ``slack_s`` seconds."""
    table = table.assign(measured=measured_seconds(results, table))
    per_stage = table.groupby("stage").agg(
        estimated=("seconds", "sum"), measured=("measured", "sum")
    )
    per_stage.loc["whole DAG"] = [table.seconds.sum(), table.measured.sum()]
    per_stage["ratio"] = per_stage.estimated / per_stage.measured
    within = (per_stage.ratio <= factor) & (per_stage.ratio >= 1 / factor)
    close = (per_stage.estimated - per_stage.measured).abs() <= slack_s
    per_stage["within_factor"] = within | close
    return per_stage


def calibrate(runs: Sequence[tuple[Path, Sequence[str]]]) -> pd.DataFrame:
    """Per rule ``fixed_s, per_unit_s, fixed_mb, per_unit_mb``: least-squares lines
    (non-negative) through every job of the given finished runs."""
    samples = []
    for results, configfiles in runs:
        cfg = load_config(configfiles)
        for job in dag_jobs(configfiles):
            file = results.parent / job.benchmark
            if not file.is_file():
                continue
            bench = pd.read_csv(file, sep="\t").iloc[0]
            units, mem_units = costs.work(job.rule, cfg, job.wildcards)
            samples.append((job.rule, units, float(bench["s"]), mem_units, float(bench["max_rss"])))
    frame = pd.DataFrame(samples, columns=["rule", "units", "seconds", "mem_units", "mem_mb"])
    rows = []
    for rule, part in frame.groupby("rule"):
        fixed_s, per_unit_s = _line(part.units.to_numpy(), part.seconds.to_numpy())
        fixed_mb, per_unit_mb = _line(part.mem_units.to_numpy(), part.mem_mb.to_numpy())
        rows.append(
            {
                "rule": rule,
                "fixed_s": fixed_s,
                "per_unit_s": per_unit_s,
                "fixed_mb": fixed_mb,
                "per_unit_mb": per_unit_mb,
                "samples": len(part),
            }
        )
    return pd.DataFrame(rows)


def average_fits(fits: Sequence[pd.DataFrame]) -> pd.DataFrame:
    """One ``costs.csv`` table from fits of :func:`calibrate` to runs on different
    machines: per rule the mean of the time coefficients (so estimates sit between the
    machines' speeds, which differ by up to 3x between otherwise equal 2-core machines),
    the largest memory coefficients (memory does not depend on the machine's speed; the
    scheduler's request must cover each), the samples summed. A rule in only some fits
    takes their values."""
    frame = pd.concat(fits, ignore_index=True)
    grouped = frame.groupby("rule", sort=True)
    out = grouped.agg(
        fixed_s=("fixed_s", "mean"),
        per_unit_s=("per_unit_s", "mean"),
        fixed_mb=("fixed_mb", "max"),
        per_unit_mb=("per_unit_mb", "max"),
        samples=("samples", "sum"),
    )
    return out.reset_index()


def _line(x: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """``a + b x`` fitting ``y`` with ``a, b >= 0`` (a constant where ``x`` does not vary)."""
    if np.ptp(x) == 0:
        return float(y.mean()), 0.0
    b, a = np.polyfit(x, y, 1)
    if a < 0:
        return 0.0, float((x @ y) / (x @ x))
    if b < 0:
        return float(y.mean()), 0.0
    return float(a), float(b)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--configfile", nargs="*", default=[], help="config files, as Snakemake's")
    parser.add_argument("--check", type=Path, help="a finished run's results folder")
    parser.add_argument("--factor", type=float, default=CHECK_FACTOR)
    parser.add_argument(
        "--limits",
        nargs=2,
        type=float,
        metavar=("MINUTES", "MEM_MB"),
        help="a partition's time and memory limits every job's request must fit",
    )
    parser.add_argument(
        "--calibrate", nargs="+", metavar="RESULTS:CONFIG", help="finished runs to fit costs.csv to"
    )
    parser.add_argument(
        "--average-with",
        nargs="+",
        default=[],
        type=Path,
        metavar="CSV",
        help="with --calibrate: earlier fits (costs.csv of runs on other machines) to average "
        "the new fit with (plan.average_fits)",
    )
    args = parser.parse_args(argv)
    if args.average_with and not args.calibrate:
        parser.error("--average-with needs --calibrate")
    if args.calibrate:
        pairs = (item.split(":", 1) for item in args.calibrate)
        runs = [(Path(r), [f for f in c.split(",") if f]) for r, c in pairs]
        earlier = [io.read_csv(p, required=FIT_COLUMNS, text=("rule",)) for p in args.average_with]
        table = calibrate(runs)
        if earlier:
            table = average_fits([table, *earlier])
        out = Path(costs.__file__).with_name("costs.csv")
        table.round(6).to_csv(out, index=False)
        print(f"wrote {out}:\n{table.to_string(index=False)}")
        return 0
    cfg = load_config(args.configfile)
    table = estimates(cfg, dag_jobs(args.configfile))
    if cfg["gpus"] and not gpu_seconds_per_unit():
        print(
            "no GPU rates measured yet (benchmarks/results/gpu_check_*.csv, from "
            "benchmarks/gpu_check.sh): GPU jobs are counted at their CPU times"
        )
    print(summary(table).round(3).to_string())
    if args.limits:
        over = beyond_limits(table, *args.limits)
        minutes, mem_mb = args.limits
        if len(over):
            print(f"\n{len(over)} jobs ask for more than {minutes:g} min or {mem_mb:g} MB:")
            print(over.to_string(index=False))
            return 1
        print(f"\nevery job's request fits {minutes:g} min and {mem_mb:g} MB")
    if args.check:
        result = check(table, args.check, args.factor)
        print(
            f"\nestimated vs measured job seconds (accepted within a factor of {args.factor}"
            f" or {CHECK_SLACK_S:g} s):"
        )
        print(result.round(2).to_string())
        return 0 if result.within_factor.all() else 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
