from neurender.logs import log_to_file
from neurender.mitsuba_setup import require_mitsuba
from neurender.simplify.stage import prepare_case

log_to_file(snakemake.log[0])
cfg = snakemake.params.cfg
mi, _ = require_mitsuba(cfg["device"])
prepare_case(snakemake.wildcards.case, cfg, mi, dict(snakemake.output.items()))
