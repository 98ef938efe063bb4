from neurender.logs import log_to_file
from neurender.prt.model import run_momoprt

log_to_file(snakemake.log[0])
inp = snakemake.input
run_momoprt(
    inp.seq,
    {s: inp[f"{s}_dir"] for s in ("train", "val")},
    {s: inp[f"{s}_manifest"] for s in ("train", "val")},
    snakemake.wildcards.material,
    snakemake.params.cfg,
    snakemake.output.model,
)
