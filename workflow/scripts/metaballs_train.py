from neurender.logs import log_to_file
from neurender.metaballs.model import train_generator

log_to_file(snakemake.log[0])
train_generator(
    dict(snakemake.input.items()),
    snakemake.params.cfg,
    snakemake.threads,
    snakemake.output.checkpoint,
    snakemake.output.loss,
)
