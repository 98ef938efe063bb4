from neurender.logs import log_to_file
from neurender.report import build_report

log_to_file(snakemake.log[0])
build_report(
    snakemake.input.tables,
    snakemake.input.figures,
    snakemake.output.html,
    snakemake.params.title,
    {"config": ", ".join(snakemake.params.configfiles), "seed": str(snakemake.params.seed)},
)
