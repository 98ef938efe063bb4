#!/usr/bin/env bash
# The prepared GPU check (benchmarks/gpu_check.py): run it on a bare GPU machine that has
# PyTorch but not our other packages and no network, from the repository root:
#
#   bash benchmarks/gpu_bundle.sh            # here, once: the few wheels the check needs
#   python benchmarks/gpu_check.py make-data results benchmarks/gpu_check_data.npz
#   # then, on the GPU machine, with .whl/ and benchmarks/gpu_check_data.npz copied along:
#   bash benchmarks/gpu_check.sh             # writes benchmarks/results/gpu_check_<GPU>.csv
#
# It takes about 5 minutes on one H100/H200-class GPU. Commit the CSV: `python -m
# neurender.plan` then estimates GPU-hours from its rates.
set -euo pipefail
cd "$(dirname "$0")/.."
if [ -d .whl ] && compgen -G ".whl/*.whl" >/dev/null; then
  python3 -m pip install -q --no-index --no-deps --no-compile --target /tmp/neurender-site .whl/*.whl
  export PYTHONPATH=/tmp/neurender-site:${PYTHONPATH:-}
fi
export PYTHONPATH=$PWD/src:${PYTHONPATH:-} PYTHONUNBUFFERED=1
out=${OUT:-benchmarks/results}
mkdir -p "$out"
gpu=$(python3 -c "import torch; print(torch.cuda.get_device_name().replace(' ', '_'))")
python3 benchmarks/gpu_check.py run benchmarks/gpu_check_data.npz "$out/gpu_check_${gpu}.csv" --steps 20
