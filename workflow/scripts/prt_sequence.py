from neurender.logs import log_to_file
from neurender.prt.data import make_sequence

log_to_file(snakemake.log[0])
make_sequence(
    snakemake.wildcards.object, snakemake.input.gim, snakemake.params.cfg, snakemake.output.seq
)
