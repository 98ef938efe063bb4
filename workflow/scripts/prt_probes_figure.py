from neurender.logs import log_to_file
from neurender.prt.data import probes_figure

log_to_file(snakemake.log[0])
probes_figure(snakemake.input.exrs, snakemake.input.sh, snakemake.output.png)
