from neurender.logs import log_to_file
from neurender.mitsuba_setup import require_mitsuba
from neurender.simplify.stage import optimise_case

log_to_file(snakemake.log[0])
cfg = snakemake.params.cfg
mi, dr = require_mitsuba(cfg["device"])
dr.set_thread_count(snakemake.threads)
optimise_case(
    snakemake.wildcards.case,
    cfg,
    mi,
    dr,
    dict(snakemake.input.items()),
    dict(snakemake.output.items()),
)
