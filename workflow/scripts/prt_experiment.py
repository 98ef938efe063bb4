from neurender.logs import log_to_file
from neurender.prt.evaluate import evaluate_experiment

log_to_file(snakemake.log[0])
inp = snakemake.input
evaluate_experiment(
    snakemake.wildcards.object,
    inp.seq,
    inp.test_dir,
    inp.test_manifest,
    inp.deepprt,
    inp.onnx,
    inp.momoprt,
    inp.light[0],
    snakemake.params.cfg,
    snakemake.threads,
    snakemake.output.csv,
    snakemake.output.figure,
)
