from neurender.logs import log_to_file
from neurender.prt.data import noise_floor

log_to_file(snakemake.log[0])
noise_floor(
    snakemake.wildcards.object,
    snakemake.input.seq,
    snakemake.input.reference,
    snakemake.input.light[0],
    snakemake.params.cfg,
    snakemake.threads,
    snakemake.output.csv,
)
