"""What a finished run must have made: its files and what each holds, as a manifest that a
later run is checked against.

A manifest is a tidy CSV, one row per file pattern and field:

* ``pattern``: a path under the results folder, ``/``-separated, each run of three or more
  digits written ``*`` (one row stands for a numbered set: ``prt/head/test/frame_*.exr``);
* ``files``: how many files the pattern matches;
* ``field``: a CSV column, an EXR channel, an NPZ array or a JSON object's top-level key,
  in the file's order; blank for a file that holds no named fields (PNG, meshes, ONNX).

Checking a run against it fails on a pattern that matches another number of files, a file
whose fields differ from the pattern's, a CSV without a data row, and a file that no
pattern lists. Job logs and benchmark files (``logs/``, ``benchmarks/``: one per job, so
the DAG's concern), TensorBoard's event files (their names hold a time and a host) and
hidden files (Snakemake's markers) are not listed.

    python -m neurender.output_manifest write results tests/data/smoke_outputs.csv
    python -m neurender.output_manifest check results tests/data/smoke_outputs.csv
"""

from __future__ import annotations

import argparse
import csv
import json
import re
import sys
import zipfile
from collections.abc import Iterable
from pathlib import Path

import OpenEXR
import pandas as pd

from neurender import io

#: Top-level folders of the results not listed (one file per job).
NOT_LISTED_FOLDERS = ("logs", "benchmarks")
#: Files not listed wherever they are: TensorBoard's event files.
NOT_LISTED_NAME = re.compile(r"events\.out\.tfevents\..*")
#: A numbered file's number: three digits or more (``frame_0007``, ``000123``).
NUMBER = re.compile(r"\d{3,}")
COLUMNS = ["pattern", "files", "field"]


def listed_files(results: Path) -> list[Path]:
    """Every file under ``results`` a manifest lists, as paths relative to it, sorted."""
    files = []
    for path in results.rglob("*"):
        rel = path.relative_to(results)
        if not path.is_file() or rel.parts[0] in NOT_LISTED_FOLDERS:
            continue
        if any(part.startswith(".") for part in rel.parts) or NOT_LISTED_NAME.fullmatch(path.name):
            continue
        files.append(rel)
    return sorted(files)


def pattern_of(rel: Path) -> str:
    """The manifest pattern of a relative path: each run of 3+ digits as ``*``."""
    return NUMBER.sub("*", rel.as_posix())


def numbered_sets(results: Path) -> dict[str, list[Path]]:
    """The listed files of ``results``, relative to it, by pattern (sorted)."""
    sets: dict[str, list[Path]] = {}
    for rel in listed_files(results):
        sets.setdefault(pattern_of(rel), []).append(rel)
    return sets


def fields(path: Path) -> list[str]:
    """The named fields a file holds, in its order (see the module docstring); ``[]`` for
    a format without them.

    Raises:
        OSError: naming the file when it cannot be read as its suffix says.
    """
    suffix = path.suffix.lower()
    try:
        if suffix == ".csv":
            with open(path, newline="", encoding="utf-8") as f:
                return next(csv.reader(f), [])
        if suffix == ".exr":
            with OpenEXR.File(str(path), header_only=True) as f:
                return [c.name for c in f.header()["channels"]]
        if suffix == ".npz":
            with zipfile.ZipFile(path) as z:
                return [n.removesuffix(".npy") for n in z.namelist()]
        if suffix == ".json":
            data = json.loads(path.read_text(encoding="utf-8"))
            return list(data) if isinstance(data, dict) else []
    except (OSError, RuntimeError, ValueError, zipfile.BadZipFile) as err:
        raise OSError(f"cannot read the fields of {path}: {err}") from err
    return []


def describe(results: str | Path) -> pd.DataFrame:
    """The manifest of a finished run's ``results`` folder (columns :data:`COLUMNS`).

    Raises:
        ValueError: naming two files of one numbered set whose fields differ.
    """
    results = Path(results)
    rows = []
    for pattern, members in numbered_sets(results).items():
        first = fields(results / members[0])
        for rel in members[1:]:
            if fields(results / rel) != first:
                raise ValueError(
                    f"{results / rel} and {results / members[0]} (both {pattern}) hold "
                    "different fields; name them so that they are two patterns"
                )
        rows += [(pattern, len(members), f) for f in first or [""]]
    return pd.DataFrame(rows, columns=COLUMNS)


def write(results: str | Path, manifest: str | Path) -> None:
    """Write the manifest of the run in ``results`` to ``manifest`` (atomically)."""
    io.write_csv(manifest, describe(results))


def _has_data_row(path: Path) -> bool:
    with open(path, newline="", encoding="utf-8") as f:
        reader = csv.reader(f)
        next(reader, None)
        return any(row for row in reader)


def differences(results: str | Path, manifest: str | Path) -> list[str]:
    """Every way the run in ``results`` differs from ``manifest``, one sentence each
    naming the file or pattern; empty when it has made exactly what the manifest lists."""
    results = Path(results)
    expected = io.read_csv(manifest, COLUMNS, text=("pattern", "field"))
    made = numbered_sets(results)
    found = []
    for pattern, rows in expected.groupby("pattern", sort=True):
        want_files, want_fields = int(rows["files"].iloc[0]), [f for f in rows["field"] if f]
        members = made.pop(pattern, [])
        if len(members) != want_files:
            found.append(f"{pattern}: {len(members)} files, the manifest expects {want_files}")
        for rel in members:
            path = results / rel
            have = fields(path)
            missing = [f for f in want_fields if f not in have]
            extra = [f for f in have if f not in want_fields]
            if missing or extra:
                found.append(f"{path}: lacks fields {missing}, has fields not listed {extra}")
            if path.suffix.lower() == ".csv" and not _has_data_row(path):
                found.append(f"{path}: no data row under its header")
    for pattern, members in sorted(made.items()):
        found += [f"{results / rel}: not in the manifest ({pattern})" for rel in members]
    return found


def main(argv: Iterable[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m neurender.output_manifest", description=__doc__.split("\n\n")[0]
    )
    parser.add_argument("action", choices=("write", "check"))
    parser.add_argument("results", type=Path, help="a finished run's results folder")
    parser.add_argument("manifest", type=Path, help="the manifest CSV")
    args = parser.parse_args(None if argv is None else list(argv))
    if not args.results.is_dir():
        parser.error(f"{args.results} is not a folder")
    if args.action == "write":
        write(args.results, args.manifest)
        print(f"{args.manifest}: {len(listed_files(args.results))} files")
        return 0
    found = differences(args.results, args.manifest)
    for line in found:
        print(line, file=sys.stderr)
    if found:
        print(
            f"{len(found)} differences from {args.manifest}; if the workflow now makes these "
            f"files on purpose, rewrite it: python -m neurender.output_manifest write "
            f"{args.results} {args.manifest}",
            file=sys.stderr,
        )
        return 1
    print(f"{args.results}: every file of {args.manifest}, with its fields")
    return 0


if __name__ == "__main__":
    sys.exit(main())
