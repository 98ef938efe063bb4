from pandas import concat

from neurender.io import read_csv, write_csv
from neurender.logs import log_to_file
from neurender.mitsuba_setup import require_mitsuba
from neurender.simplify.evaluate import evaluate_cases, loss_figure

log_to_file(snakemake.log[0])
cfg = snakemake.params.cfg
mi, _ = require_mitsuba(cfg["device"])
inputs = dict(snakemake.input.items())
evaluate_cases(mi, snakemake.params.cases, cfg, inputs, dict(snakemake.output.items()))
cases = snakemake.params.cases
loss_figure([read_csv(inputs[f"{case}_loss"]) for case in cases], snakemake.output.loss_figure)
write_csv(snakemake.output.stats, concat([read_csv(inputs[f"{case}_stats"]) for case in cases]))
