#!/usr/bin/env bash
# Snakemake runs this inside the new conda env, from the workflow's working directory
# (the repository root): install the neurender package from this checkout.
set -euo pipefail
python -m pip install --no-deps -e .
