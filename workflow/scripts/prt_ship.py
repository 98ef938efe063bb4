from neurender.jobs import copy_files, run

run(snakemake, copy_files)
