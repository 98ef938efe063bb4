# Config validation and the helpers every rules file uses. Each method's rules are in
# workflow/rules/<method>.smk, its names and input functions in
# workflow/rules/helpers/<method>.smk (included before the rules files, see the Snakefile),
# what the rest of the workflow knows of it, its rules' params included, in its record
# (src/neurender/<package>/method.py, listed in neurender.methods).
from snakemake.utils import validate

import neurender.config
import neurender.methods
from neurender.user_paths import as_input, files_of, made_by_the_workflow

# Validate (and fill defaults) before any job runs: a key set twice in one config file
# (which Snakemake's reader lets the last win) fails naming the file and lines, a key an
# older release named differently fails with its new name, unknown keys and wrong types
# fail here, then the rules between keys (neurender/config.py), naming the keys and values.
neurender.config.check_files(workflow.configfiles)
neurender.config.check_renamed(config, workflow.configfiles)
neurender.config.check_names_are_text(config)
validate(config, schema="../schemas/config.schema.yaml")
neurender.config.check(config)


def rule_params(name, **given):
    """The ``params`` (``cfg``) of the jobs of ``name``, a function of a job's wildcards
    (:meth:`neurender.method.Rule.job_params`): what its registry entry declares they
    read of the config, and ``given``, the values its declaration leaves to the rules
    file (:class:`neurender.method.Given`). An edit of another key never reruns a job.
    """
    record = neurender.methods.rules()[name]

    def params(wildcards):
        return record.job_params(config, dict(wildcards), given)

    return params


def user_files(path):
    """The input files behind a user-given path: itself when the workflow makes it (under
    ``results/``, e.g. the example assets), else every visible file of a folder or the
    matches of a glob (:func:`neurender.user_paths.files_of`), so that editing any of them
    reruns the jobs that read them."""
    if made_by_the_workflow(path):
        return [as_input(path)]
    return [str(p) for p in files_of(path)]


def report_inputs(kind):
    """Every registered method's report files of one ``kind`` (``tables``, ``figures``,
    ``viewers``), methods in report order (:mod:`neurender.methods`)."""
    return [
        path
        for method in neurender.methods.METHODS
        for path in getattr(method.report_inputs(config), kind)
    ]


def scheduler_resources(rule_name):
    """A job's ``resources``: ``mem_mb`` and ``runtime`` (minutes) from the cost model
    (:mod:`neurender.costs`, estimate times a safety factor, doubled on each retry) and
    ``gpu`` (config key ``gpus``) for the rules that use a GPU. Local runs schedule on
    them too; on a cluster they become the job's ``--mem``, ``--time`` and ``--gpus``.
    """
    import neurender.costs

    def estimate(wildcards):
        return neurender.costs.estimate(rule_name, config, dict(wildcards))

    gpus = config["gpus"] if neurender.costs.uses_gpu(rule_name) else 0
    return {
        "mem_mb": lambda wildcards, attempt: estimate(wildcards).mem_limit_mb * attempt,
        "runtime": lambda wildcards, attempt: estimate(wildcards).runtime_min * attempt,
        "gpu": gpus,
    }


def report_studies(wildcards):
    """Every registered method's committed studies' CSVs and sidecars
    (:attr:`neurender.method.Method.studies`), each once, in report order: inputs of the
    report only, so that committing a study reruns nothing else."""
    files = [
        path
        for method in neurender.methods.METHODS
        for study in method.studies
        for path in (study.csv, study.sidecar, *study.figures)
    ]
    return list(dict.fromkeys(files))


def report_results(wildcards):
    """Every table, figure and viewer the report shows (also the provenance's inputs)."""
    return {kind: report_inputs(kind) for kind in ("tables", "figures", "viewers")}
