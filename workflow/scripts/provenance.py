from neurender.jobs import run
from neurender.report import jobs

run(snakemake, jobs.provenance)
