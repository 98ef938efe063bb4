from neurender.logs import log_to_file
from neurender.ndr.model import train_variant

log_to_file(snakemake.log[0])
train_variant(
    snakemake.wildcards.variant,
    dict(snakemake.input.items()),
    snakemake.params.cfg,
    snakemake.threads,
    snakemake.output.checkpoint,
    snakemake.output.loss,
)
