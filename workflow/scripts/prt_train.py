from neurender.logs import log_to_file
from neurender.prt.model import run_train

log_to_file(snakemake.log[0])
inp = snakemake.input
run_train(
    inp.seq,
    {s: inp[f"{s}_dir"] for s in ("train", "val")},
    {s: inp[f"{s}_manifest"] for s in ("train", "val")},
    snakemake.wildcards.material,
    snakemake.params.cfg,
    snakemake.threads,
    snakemake.output.checkpoint,
    snakemake.output.onnx,
    snakemake.output.loss,
)
