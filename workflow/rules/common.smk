# Config validation and the helpers every rules file uses. Each method's rules are in
# workflow/rules/<method>.smk, its names, params and input functions in
# workflow/rules/helpers/<method>.smk (included before the rules files, see the Snakefile).
import glob
from pathlib import Path

from snakemake.utils import validate

import neurender.config

# Validate (and fill defaults) before any job runs: unknown keys and wrong types fail here,
# then the rules between keys (neurender/config.py), naming the keys and values.
validate(config, schema="../schemas/config.schema.yaml")
neurender.config.check(config)


def section_keys(section, keys, top=(), **extra):
    """The config keys one job reads, for its ``params`` (``cfg``): ``keys`` of
    ``config[section]``, ``top``-level keys (``seed``, ``device``) and ``extra`` values
    (wildcards); an edit of any other key then never reruns the job."""
    cfg = {k: config[k] for k in top}
    cfg.update({k: config[section][k] for k in keys})
    cfg.update(extra)
    return cfg


def user_files(path):
    """The input files behind a user-given path: itself when the workflow makes it (under
    ``results/``, e.g. the example assets), else every file of a folder or a glob, so that
    editing any of them reruns the jobs that read them."""
    if path.startswith("results/"):
        return [path]
    if Path(path).is_dir():
        return sorted(str(p) for p in Path(path).iterdir() if p.is_file())
    if glob.has_magic(path):
        return sorted(glob.glob(path))
    return [path]


def scheduler_resources(rule_name):
    """A job's ``resources``: ``mem_mb`` and ``runtime`` (minutes) from the cost model
    (:mod:`neurender.costs`, estimate times a safety factor, doubled on each retry) and
    ``gpu`` (config key ``gpus``) for the rules that use a GPU. Local runs schedule on
    them too; on a cluster they become the job's ``--mem``, ``--time`` and ``--gpus``.
    """
    import neurender.costs

    def estimate(wildcards):
        return neurender.costs.estimate(rule_name, config, dict(wildcards))

    gpus = config["gpus"] if rule_name in neurender.costs.GPU_RULES else 0
    return {
        "mem_mb": lambda wildcards, attempt: estimate(wildcards).mem_limit_mb * attempt,
        "runtime": lambda wildcards, attempt: estimate(wildcards).runtime_min * attempt,
        "gpu": gpus,
    }
