from neurender.jobs import run
from neurender.ndr import jobs

run(snakemake, jobs.ndr_equal_quality)
