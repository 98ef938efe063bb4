from neurender.logs import log_to_file
from neurender.metaballs.evaluate import target_rows

log_to_file(snakemake.log[0])
target_rows(
    snakemake.input.metrics,
    snakemake.input.timing,
    snakemake.params.paper_scale,
    snakemake.output.targets,
)
