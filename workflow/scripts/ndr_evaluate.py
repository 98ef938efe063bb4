from neurender.logs import log_to_file
from neurender.ndr.evaluate import run_evaluation

log_to_file(snakemake.log[0])
run_evaluation(
    dict(snakemake.input.items()),
    snakemake.params.variants,
    snakemake.params.cfg,
    snakemake.threads,
    dict(snakemake.output.items()),
)
