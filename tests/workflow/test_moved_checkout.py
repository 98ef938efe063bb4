"""A checkout moved or copied elsewhere with its results (``mv``, ``cp -a``) reruns
nothing: no job records the checkout's absolute path in what Snakemake compares between
runs (``.snakemake/metadata``: params, the set of input files, a rule's code).

Snakemake makes ``--configfile`` paths absolute and ``workflow.basedir`` is absolute; a
job whose params held either reran after a move ("Params have changed since last
execution"). Tested as a user meets it, through Snakemake's public API: a checkout with a
finished smoke run (recorded by the ``touch`` executor, no job run:
:func:`tests.workflow.test_rerun_matrix.finish_smoke_run`), its Snakefile, workflow and
configs its own files, copied to another folder, where a dry run finds nothing to do.
"""

from __future__ import annotations

import shutil

from tests.workflow.test_rerun_matrix import Job, finish_smoke_run, smoke_dag

#: The checkout's own copies of what Snakemake reads as the workflow and its config, so that
#: a path of the checkout Snakemake records is the copied folder's (a link would be resolved
#: to the repository's, the same for both folders).
OWN = ("Snakefile", "workflow", "config")


def test_a_copied_checkout_with_its_results_reruns_nothing(tmp_path):
    first, moved = tmp_path / "first", tmp_path / "moved"
    first.mkdir()
    jobs = finish_smoke_run(first, copies=OWN)
    # The rules that name config files or the checkout are in the DAG, so the check covers them.
    assert {"report", "provenance"} <= {job.rule for job in jobs}
    # cp -a: the links, Snakemake's records and the outputs with their times.
    shutil.copytree(first, moved, symlinks=True)
    rerun: list[Job] = []
    with smoke_dag(moved, jobs=rerun) as dag:
        dag.execute_workflow(executor="dryrun")
    assert not rerun, [f"{job.rule} {job.output}: {job.reason}" for job in rerun]
