from neurender.logs import log_to_file
from neurender.prt.evaluate import relight_figure

log_to_file(snakemake.log[0])
inp = snakemake.input
relight_figure(
    snakemake.wildcards.object,
    inp.seq,
    inp.test_dir,
    inp.test_manifest,
    inp.deepprt,
    inp.onnx,
    inp.probes,
    snakemake.params.cfg,
    snakemake.threads,
    snakemake.output.csv,
    snakemake.output.figure,
)
