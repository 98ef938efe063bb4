from neurender.logs import log_to_file
from neurender.ndr.summary import summarise

log_to_file(snakemake.log[0])
out = snakemake.output
summarise(
    dict(zip(snakemake.params.splits, snakemake.input.manifests, strict=True)),
    snakemake.input.example,
    snakemake.params.cfg,
    out.csv,
    out.furnace,
    out.figure,
)
