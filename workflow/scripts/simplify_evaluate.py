from neurender.logs import log_to_file
from neurender.mitsuba_setup import require_mitsuba
from neurender.simplify.evaluate import evaluate_cases

log_to_file(snakemake.log[0])
cfg = snakemake.params.cfg
mi, dr = require_mitsuba(cfg["device"])
evaluate_cases(
    mi,
    dr,
    snakemake.params.cases,
    cfg,
    dict(snakemake.input.items()),
    dict(snakemake.output.items()),
)
