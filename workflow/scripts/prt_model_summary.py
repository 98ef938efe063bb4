from itertools import product

from neurender.logs import log_to_file
from neurender.prt.evaluate import summarise_models
from neurender.prt.model import MATERIALS

log_to_file(snakemake.log[0])
inp, objects = snakemake.input, snakemake.params.objects
keys = list(product(objects, MATERIALS))  # the order of expand() in the rule
summarise_models(
    objects,
    inp.metrics,
    inp.experiments,
    dict(zip(keys, inp.checkpoints, strict=True)),
    dict(zip(keys, inp.onnx, strict=True)),
    dict(zip(keys, inp.losses, strict=True)),
    {obj: inp.frames[3 * i : 3 * i + 3] for i, obj in enumerate(objects)},
    snakemake.params.cfg,
    snakemake.output.metrics,
    snakemake.output.compression,
    snakemake.output.targets,
    snakemake.output.loss,
    snakemake.output.equal_quality,
)
