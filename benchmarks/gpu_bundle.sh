#!/usr/bin/env bash
# Wheels the GPU check needs beyond what a PyTorch GPU image holds (numpy, pandas, onnx,
# onnxruntime, onnxscript, tqdm): OpenEXR, pypng, kornia and kornia_rs, for CPython 3.12
# on x86-64 Linux, into .whl/ (git-ignored; about 9 MB). Set PYTHON_VERSION for another.
set -euo pipefail
cd "$(dirname "$0")/.."
version=${PYTHON_VERSION:-3.12}
platforms=(manylinux_2_28_x86_64 manylinux_2_27_x86_64 manylinux_2_17_x86_64 manylinux2014_x86_64)
args=(--no-deps --only-binary=:all: --python-version "$version" --implementation cp -d .whl)
for p in "${platforms[@]}"; do args+=(--platform "$p"); done
python3 -m pip download -q "${args[@]}" OpenEXR pypng kornia kornia_rs
du -sh .whl
