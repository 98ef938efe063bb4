from neurender.logs import log_to_file
from neurender.prt.evaluate import evaluate_object
from neurender.prt.model import MATERIALS

log_to_file(snakemake.log[0])
inp = snakemake.input
evaluate_object(
    snakemake.wildcards.object,
    inp.seq,
    {s: inp[f"{s}_dir"] for s in ("val", "test")},
    {s: inp[f"{s}_manifest"] for s in ("val", "test")},
    dict(zip(MATERIALS, inp.deepprt, strict=True)),
    dict(zip(MATERIALS, inp.onnx, strict=True)),
    dict(zip(MATERIALS, inp.momoprt, strict=True)),
    inp.light[0],
    snakemake.params.cfg,
    snakemake.threads,
    snakemake.output.metrics,
    snakemake.output.frames,
    snakemake.output.figure,
)
