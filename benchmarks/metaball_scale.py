"""Commit a run of the metaballs' scale study (config/studies/metaballs_scale.yaml): copies
the run's measurements and figures from its checkout's ``results/metaballs/`` into
``benchmarks/results/`` as ``metaball_scale*.csv``, ``metaball_real_scenes.csv`` and their
figures, each CSV with a sidecar naming the command that made it and the run checkout's
commit, which the report's committed studies show.

python benchmarks/metaball_scale.py /path/to/study/checkout \\
    --command "snakemake --cores 2 results/metaballs/scale.csv ..." --note "..."
"""

import argparse
from pathlib import Path

from neurender import io
from neurender.provenance import git_state

ROOT = Path(__file__).resolve().parent.parent
#: Run file (under ``results/metaballs/``) to committed name (under ``benchmarks/results/``).
FILES = {
    "scale.csv": "metaball_scale.csv",
    "scale_equal_quality.csv": "metaball_scale_equal_quality.csv",
    "real_scenes.csv": "metaball_real_scenes.csv",
    "figures/scale.png": "metaball_scale.png",
    "figures/real_scenes.png": "metaball_real_scenes.png",
    "figures/trajectory.gif": "metaball_trajectory.gif",
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("run", type=Path, help="the study run's checkout")
    parser.add_argument("--command", required=True, help="the command that made the run")
    parser.add_argument("--note", default="", help="how it ran (machine, load, wall time)")
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results")
    args = parser.parse_args()
    state = git_state(args.run)
    if state["commit"] is None:
        raise SystemExit(f"{args.run}: not a git checkout; the sidecar needs its commit")
    record = {"command": args.command, **state, "note": args.note}
    args.out.mkdir(parents=True, exist_ok=True)
    for source, name in FILES.items():
        path = args.run / "results" / "metaballs" / source
        if not path.is_file():
            raise SystemExit(f"{path}: missing; run the study's command first")
        io.copy_file(path, args.out / name)
        if name.endswith(".csv"):
            io.write_json(args.out / Path(name).with_suffix(".json"), {"runs": [record]})


if __name__ == "__main__":
    main()
