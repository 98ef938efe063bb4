from neurender import examples
from neurender.jobs import run

run(snakemake, examples.example_assets)
