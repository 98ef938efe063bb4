from neurender.logs import log_to_file
from neurender.prt.data import summarise

log_to_file(snakemake.log[0])
summarise(
    snakemake.input.gim,
    snakemake.input.manifests,
    snakemake.input.noise,
    snakemake.output.data,
    snakemake.output.noise,
)
