# Config validation and the helpers every rules file uses; each method's own helpers
# live in its rules file.
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
