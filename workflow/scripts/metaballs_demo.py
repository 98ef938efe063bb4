from neurender.logs import log_to_file
from neurender.metaballs.demo import run_demo
from neurender.metaballs.model import MetaballRenderer

log_to_file(snakemake.log[0])
cfg, out = snakemake.params.cfg, snakemake.output
run_demo(
    {
        variant: MetaballRenderer(path, cfg["device"], snakemake.threads)
        for variant, path in zip(
            snakemake.params.variants, snakemake.input.checkpoints, strict=True
        )
    },
    cfg,
    out.frames,
    out.timing,
    out.balls,
    out.balls_png,
    out.gif,
    out.strip,
    out.stability,
)
