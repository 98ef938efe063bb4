from neurender.logs import log_to_file
from neurender.prt.benchmark import run_benchmark
from neurender.prt.data import read_sh_light

log_to_file(snakemake.log[0])
run_benchmark(
    snakemake.input.seq[0],
    read_sh_light(snakemake.input.light[0]),
    snakemake.params.cfg,
    snakemake.threads,
    snakemake.output.csv,
)
