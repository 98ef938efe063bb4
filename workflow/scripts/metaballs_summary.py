from neurender.logs import log_to_file
from neurender.metaballs.data import summarise

log_to_file(snakemake.log[0])
summarise(
    snakemake.input.manifests,
    snakemake.output.csv,
    snakemake.output.figure,
    snakemake.input.examples,
)
