from neurender.logs import log_to_file
from neurender.metaballs.model import train_pix2pix

log_to_file(snakemake.log[0])
inp = snakemake.input
train_pix2pix(
    inp.train_dir,
    inp.train_manifest,
    inp.val_dir,
    inp.val_manifest,
    snakemake.params.cfg,
    snakemake.threads,
    snakemake.output.checkpoint,
    snakemake.output.loss,
)
