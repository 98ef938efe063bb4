from neurender.logs import log_to_file
from neurender.metaballs.demo import run_demo
from neurender.metaballs.model import Pix2PixRenderer

log_to_file(snakemake.log[0])
cfg, out = snakemake.params.cfg, snakemake.output
run_demo(
    Pix2PixRenderer(snakemake.input.checkpoint, cfg["device"], snakemake.threads),
    cfg,
    out.frames,
    out.timing,
    out.balls,
    out.balls_png,
    out.gif,
    out.strip,
    out.stability,
)
