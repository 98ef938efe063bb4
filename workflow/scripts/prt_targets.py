from neurender.jobs import run
from neurender.prt import jobs

run(snakemake, jobs.prt_targets)
