#!/usr/bin/env bash
# Regenerates requirements.lock, the exact versions CI installs: pyproject.toml's
# dependencies and its dev and slurm extras, with torch the CPU wheel that requirements.in
# names, for CPython 3.11 on x86-64 Linux, each with the sha256 hashes of its files (pip's
# hash-checking mode). Then rewrites the exact runtime pins of workflow/envs/neurender.yaml
# (the rules' conda env) from it; tests/test_lock.py checks that the three files agree.
#
#   scripts/update-lock.sh
#
# Needs uv (pip install uv) and the network. TORCH_WHEELS is where the CPU wheel of torch
# lies (a folder or a page of links; default PyPI's torch page on PyTorch's CPU index);
# everything else comes from PyPI.
set -euo pipefail
cd "$(dirname "$0")/.."
torch_wheels=${TORCH_WHEELS:-https://download.pytorch.org/whl/cpu/torch/}
args=(--python-version 3.11 --python-platform x86_64-manylinux_2_28 --find-links "$torch_wheels")
uv pip compile -q pyproject.toml requirements.in --extra dev --extra slurm "${args[@]}" \
  --generate-hashes --custom-compile-command "scripts/update-lock.sh" -o requirements.lock
# The runtime subset at the lock's versions (no extras, no hashes).
uv pip compile -q pyproject.toml requirements.in -c requirements.lock "${args[@]}" \
  --no-header --no-annotate -o /tmp/neurender-runtime-pins.txt
python3 - /tmp/neurender-runtime-pins.txt <<'PY'
import re
import sys
from pathlib import Path

pins = [line.strip() for line in Path(sys.argv[1]).read_text().splitlines() if "==" in line]
# The rules' env also runs config/paper.yaml's GPU jobs on a cluster: it takes the lock's
# torch release as PyPI's Linux build, which has CUDA (the CPU wheel would leave them on
# the CPU).
pins = [re.sub(r"^torch==([^+]+)\+cpu$", r"torch==\1", p) for p in pins]
env = Path("workflow/envs/neurender.yaml")
head = env.read_text().split("  - pip:\n")[0]
env.write_text(head + "  - pip:\n" + "".join(f"      - {p}\n" for p in pins))
PY
echo "requirements.lock: $(grep -c '^[A-Za-z0-9]' requirements.lock) packages;" \
  "workflow/envs/neurender.yaml: $(grep -c '==' workflow/envs/neurender.yaml) pins"
