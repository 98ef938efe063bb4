from neurender.logs import log_to_file
from neurender.ndr.evaluate import target_rows

log_to_file(snakemake.log[0])
target_rows(
    snakemake.input.metrics,
    list(snakemake.input.benchmarks),
    snakemake.params.job_threads,
    snakemake.params.cores,
    snakemake.output.targets,
)
