"""Compare two ``results/`` folders of the same config: are the deterministic outputs equal?

Run as ``python -m neurender.compare RESULTS_A RESULTS_B``. First the two runs'
provenance (``provenance.json``, :mod:`neurender.provenance`) is compared: what made them
differ (commit, dirty tree, package versions, config keys; never the run's times) is
printed before any output is. Then every CSV and EXR under ``RESULTS_A`` (but the
``benchmarks`` and ``tensorboard`` folders, which hold measurements of the machine) is
compared with its counterpart byte for byte. A CSV that differs is
compared again without its wall-clock measurements (columns and metrics named like
seconds, milliseconds, rays per second, speed-ups or minutes, which no two runs share);
it passes if that is all that differs. The exit status is 1 when any other difference, or
a missing file, is found.
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

import pandas as pd

from neurender import io, provenance

#: Folders under ``results/`` that no two runs share (timings, training event files).
SKIPPED_FOLDERS = ("benchmarks", "tensorboard")

#: Names of measurements that depend on the machine's speed at the moment of the run.
TIMING = re.compile(
    r"(^|_)(s|ms|seconds?|minutes|rays_per_s|speedup|time|fraction_of_embree)(_|$)"
    r"|_ms_|per_s|_seconds|seconds_|speedup|minutes|timing|time_vs|speed ratio",
)


def is_timing(name: str) -> bool:
    """Whether a column, metric or quantity name is a wall-clock measurement."""
    return bool(TIMING.search(str(name)))


def without_timing(frame: pd.DataFrame) -> pd.DataFrame:
    """``frame`` without timing columns and without rows whose label names a timing."""
    keep = [c for c in frame.columns if not is_timing(c)]
    frame = frame[keep]
    for label in ("metric", "quantity", "split", "check", "target"):
        if label in frame.columns:
            frame = frame[~frame[label].astype(str).map(is_timing)]
    return frame.reset_index(drop=True)


def compare_file(a: Path, b: Path) -> str:
    """``identical``, ``timing only`` (CSV whose differences are timings), ``missing`` or
    ``differs``."""
    if not b.is_file():
        return "missing"
    if a.read_bytes() == b.read_bytes():
        return "identical"
    if a.suffix == ".csv":
        ta, tb = without_timing(io.read_csv(a)), without_timing(io.read_csv(b))
        if ta.shape == tb.shape and ta.equals(tb):
            return "timing only"
    return "differs"


def compare_results(first: Path, second: Path) -> dict[str, list[str]]:
    """Every CSV and EXR under ``first`` by outcome (see :func:`compare_file`)."""
    outcome: dict[str, list[str]] = {}
    for path in sorted(first.rglob("*")):
        relative = path.relative_to(first)
        if path.suffix not in (".csv", ".exr") or set(relative.parts) & set(SKIPPED_FOLDERS):
            continue
        outcome.setdefault(compare_file(path, second / relative), []).append(str(relative))
    return outcome


def provenance_lines(first: Path, second: Path) -> list[str]:
    """What tells the two runs apart (:func:`neurender.provenance.differences`), or which
    of them has no ``provenance.json``."""
    files = [first / "provenance.json", second / "provenance.json"]
    missing = [str(f) for f in files if not f.is_file()]
    if missing:
        return [f"no provenance file: {', '.join(missing)}"]
    lines = provenance.differences(*(provenance.read(f) for f in files))
    return lines or ["same commit, packages and config"]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("first", type=Path)
    parser.add_argument("second", type=Path)
    args = parser.parse_args(argv)
    print("provenance:")
    for line in provenance_lines(args.first, args.second):
        print(f"  {line}")
    outcome = compare_results(args.first, args.second)
    for kind in ("identical", "timing only", "differs", "missing"):
        files = outcome.get(kind, [])
        print(f"{kind}: {len(files)} files")
        if kind in ("timing only", "differs", "missing"):
            for f in files:
                print(f"  {f}")
    return 1 if outcome.get("differs") or outcome.get("missing") else 0


if __name__ == "__main__":
    sys.exit(main())
