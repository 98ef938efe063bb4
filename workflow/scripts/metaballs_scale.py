from neurender.jobs import run
from neurender.metaballs import jobs

run(snakemake, jobs.metaballs_scale)
