from neurender.logs import log_to_file
from neurender.mitsuba_setup import import_mitsuba
from neurender.simplify.stage import optimise_case

log_to_file(snakemake.log[0])
cfg = snakemake.params.cfg
mi, dr = import_mitsuba(cfg["device"])
optimise_case(
    snakemake.wildcards.case,
    cfg,
    mi,
    dr,
    dict(snakemake.input.items()),
    dict(snakemake.output.items()),
)
