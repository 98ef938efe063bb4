from neurender.jobs import run
from neurender.simplification import jobs

run(snakemake, jobs.simplification_summary)
