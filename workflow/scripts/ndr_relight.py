from neurender.logs import log_to_file
from neurender.mitsuba_setup import require_mitsuba
from neurender.ndr.relight import relight

log_to_file(snakemake.log[0])
cfg = snakemake.params.cfg
mi, _ = require_mitsuba(cfg["device"])
relight(
    mi,
    cfg,
    snakemake.input.checkpoint,
    cfg["relight_sample"],
    cfg["relight_turns"],
    snakemake.threads,
    snakemake.output.csv,
    snakemake.output.figure,
)
