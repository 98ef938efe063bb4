from neurender.logs import log_to_file
from neurender.metaballs.data import generate_split

log_to_file(snakemake.log[0])
out = snakemake.output
generate_split(
    snakemake.wildcards.split,
    snakemake.params.cfg,
    snakemake.threads,
    out.examples,
    out.manifest,
    out.balls,
)
