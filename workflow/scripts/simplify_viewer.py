from neurender.jobs import run
from neurender.simplify import jobs

run(snakemake, jobs.simplify_viewer)
