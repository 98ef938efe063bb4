from neurender.jobs import run
from neurender.prt import data_jobs

run(snakemake, data_jobs.prt_benchmark)
