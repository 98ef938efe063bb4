"""A checkout moved or copied elsewhere with its results (``mv``, ``cp -a``) reruns
nothing: no job records the checkout's absolute path in what Snakemake compares between
runs (``.snakemake/metadata``: params, the set of input files, a rule's code).

Snakemake makes ``--configfile`` paths absolute and ``workflow.basedir`` is absolute; a
job whose params held either reran after a move ("Params have changed since last
execution"). The DAG of the smoke config (every rule) is built in-process through
Snakemake's API, in a spawned process (Snakemake changes the working directory and holds
global state); no results are needed.
"""

from __future__ import annotations

import multiprocessing
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def recorded_values() -> dict[str, list[str]]:
    """Per rule of the smoke DAG, what Snakemake records per output to compare with the
    next run: each job's params, input files and code (``persistence._params``,
    ``_input``, ``_code``), the config file given absolute as the command line gives it."""
    from snakemake.api import SnakemakeApi
    from snakemake.settings.types import (
        ConfigSettings,
        DAGSettings,
        OutputSettings,
        Quietness,
        ResourceSettings,
    )

    with SnakemakeApi(OutputSettings(quiet={Quietness.ALL})) as api:
        dag_api = api.workflow(
            resource_settings=ResourceSettings(cores=2),
            config_settings=ConfigSettings(configfiles=[ROOT / "config/smoke.yaml"]),
            snakefile=ROOT / "Snakefile",
            workdir=ROOT,
        ).dag(DAGSettings(targets={"results/report.html"}))
        workflow = dag_api.workflow_api._workflow
        workflow._prepare_dag(forceall=False, ignore_incomplete=False, lock_warn_only=True)
        workflow._build_dag()
        persistence = workflow.persistence
        found: dict[str, list[str]] = {}
        for job in workflow.dag.jobs:
            values = [*persistence._params(job), *persistence._input(job)]
            values.append(persistence._code(job.rule) or "")
            found.setdefault(job.rule.name, []).extend(map(str, values))
        return found


def test_no_job_records_the_checkouts_absolute_path():
    with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
        found = pool.submit(recorded_values).result()
    # The rules that name config files or the checkout are in the DAG, so the check covers them.
    assert {"report", "provenance"} <= set(found)
    root = str(ROOT)
    absolute = {
        rule: [v[max(v.index(root) - 80, 0) : v.index(root) + 80] for v in values if root in v]
        for rule, values in found.items()
        if any(root in v for v in values)
    }
    assert not absolute, absolute
