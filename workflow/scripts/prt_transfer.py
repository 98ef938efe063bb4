from neurender.logs import log_to_file
from neurender.prt.data import compute_transfer

log_to_file(snakemake.log[0])
compute_transfer(
    snakemake.wildcards.object,
    snakemake.input.seq,
    snakemake.input.light[0],
    snakemake.wildcards.split,
    snakemake.params.directions,
    snakemake.params.cfg,
    snakemake.threads,
    snakemake.output.frames,
    snakemake.output.manifest,
)
