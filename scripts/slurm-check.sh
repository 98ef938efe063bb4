#!/usr/bin/env bash
# Runs part of the smoke workflow through profiles/slurm on a running cluster
# (scripts/local-slurm.sh start) and checks it against a finished local smoke run:
#
#   scripts/slurm-check.sh [LOCAL_RESULTS] [TARGET...]
#
# 1. In a fresh copy of the checkout, the targets' jobs go through sbatch; every one of
#    them must show up in sacct as COMPLETED.
# 2. Their CSV and EXR outputs must equal the local run's (python -m neurender.compare;
#    only timings may differ).
# 3. A job given a bad input fails, and Snakemake's error names the job's SLURM log file.
set -euo pipefail
cd "$(dirname "$0")/.."
LOCAL=${1:-results}
shift || true
TARGETS=("$@")
if [ ${#TARGETS[@]} -eq 0 ]; then
  # The metaballs chain (examples -> three trainings -> evaluation: three dependency levels)
  # and one case of the simplification's Mitsuba chain (prepare -> optimise: Mitsuba on a
  # compute node; its reference EXRs compared), the smallest; all three cases would add
  # two minutes to CI and nothing the one does not check.
  TARGETS=(results/metaballs/metrics.csv results/simplification/metaballs/optimised.glb)
fi
[ -d "$LOCAL" ] || { echo "slurm-check: no local results at $LOCAL" >&2; exit 2; }
LOCAL=$(cd "$LOCAL" && pwd)

work=$(mktemp -d /tmp/neurender-slurm-check.XXXXXX)
trap 'rm -rf "$work"' EXIT
git ls-files -co --exclude-standard -z | xargs -0 -I{} cp --parents {} "$work"/ 2>/dev/null
[ -e .venv ] && ln -s "$(pwd)/.venv" "$work/.venv"
cd "$work"

run() {
  snakemake "$@" --profile profiles/slurm --configfile config/smoke.yaml \
    --slurm-init-seconds-before-status-checks 2
}

echo "slurm-check: ${TARGETS[*]} through sbatch"
start=$(date +%s)
run "${TARGETS[@]}" 2>&1 | tee slurm-run.log | grep -E "^(rule|localrule) |Job [0-9]+ has been submitted|steps \(" || true
grep -q "steps (100%) done" slurm-run.log || { echo "slurm-check: the run failed:"; tail -n 40 slurm-run.log; exit 1; }
mapfile -t ids < <(grep -oE "SLURM jobid [0-9]+|external jobid '?[0-9]+" slurm-run.log | grep -oE "[0-9]+$" | sort -u)
[ ${#ids[@]} -gt 0 ] || { echo "slurm-check: no SLURM job ids in the log"; exit 1; }
states=$(sacct -n -X -P -o JobID,State -j "$(IFS=,; echo "${ids[*]}")")
echo "$states" | sed 's/^/  sacct: /'
bad=$(echo "$states" | grep -vc "|COMPLETED$" || true)
[ "$bad" -eq 0 ] || { echo "slurm-check: $bad jobs did not complete"; exit 1; }
echo "slurm-check: ${#ids[@]} jobs COMPLETED in $(( $(date +%s) - start )) s"

python -m neurender.compare results "$LOCAL" | tee compare.log
echo "slurm-check: outputs equal the local run's"

# A bad input: the evaluation's test manifest loses its columns.
echo "garbage" > results/metaballs/test_manifest.csv
if run results/metaballs/metrics.csv > failure.log 2>&1; then
  echo "slurm-check: a job with a bad input did not fail"; exit 1
fi
grep -q "test_manifest.csv" failure.log || { echo "slurm-check: the error does not name the file"; tail -n 30 failure.log; exit 1; }
grep -qE "slurm_logs/.*\.log" failure.log || { echo "slurm-check: the error does not name the SLURM log"; tail -n 30 failure.log; exit 1; }
echo "slurm-check: the failing job was reported with its SLURM log:"
grep -E "slurm_logs/.*\.log" failure.log | head -n 3 | sed 's/^/  /'
