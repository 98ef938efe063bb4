from neurender.logs import log_to_file
from neurender.prt.data import make_geometry_image

log_to_file(snakemake.log[0])
make_geometry_image(
    snakemake.wildcards.object,
    snakemake.input[0] if snakemake.input else None,
    snakemake.params.cfg,
    snakemake.output.gim,
    snakemake.output.stats,
)
