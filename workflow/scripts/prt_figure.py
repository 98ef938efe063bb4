from neurender.logs import log_to_file
from neurender.prt.data import frames_figure

log_to_file(snakemake.log[0])
frames_figure(
    snakemake.wildcards.object,
    snakemake.input.frames,
    snakemake.input.light[0],
    snakemake.params.n_bands,
    snakemake.output.png,
)
