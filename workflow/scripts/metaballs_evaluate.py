from neurender.logs import log_to_file
from neurender.metaballs.evaluate import evaluate_models

log_to_file(snakemake.log[0])
inp, out = snakemake.input, snakemake.output
evaluate_models(
    inp.test_dir,
    inp.test_manifest,
    inp.test_balls,
    dict(zip(snakemake.params.variants, inp.checkpoints, strict=True)),
    snakemake.params.cfg,
    snakemake.threads,
    out.metrics,
    out.examples,
    out.by_scene,
    out.figure,
    out.scene_figure,
)
