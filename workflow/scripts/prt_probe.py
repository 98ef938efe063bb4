from neurender.logs import log_to_file
from neurender.prt.data import make_probe

log_to_file(snakemake.log[0])
make_probe(
    snakemake.wildcards.probe,
    snakemake.input[0] if snakemake.input else None,
    snakemake.params.cfg,
    snakemake.output.exr,
    snakemake.output.sh,
)
