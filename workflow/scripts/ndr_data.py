from neurender.logs import log_to_file
from neurender.ndr.data import generate_split

log_to_file(snakemake.log[0])
out = snakemake.output
cfg = snakemake.params.cfg
generate_split(
    cfg,
    snakemake.wildcards.split,
    cfg["count"],
    out.samples,
    out.manifest,
    out.lighting,
    snakemake.threads,
)
