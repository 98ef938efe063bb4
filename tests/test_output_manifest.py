"""The manifest of a run's files and fields, and the check of a run against it."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from neurender import io, methods, output_manifest, plan

ROOT = Path(__file__).resolve().parents[1]
SMOKE_MANIFEST = ROOT / "tests/data/smoke_outputs.csv"


def _run(root: Path) -> Path:
    """A tiny finished run: a table, a numbered set of EXR frames, an NPZ, a JSON, a PNG,
    and the files a manifest does not list (a log, a benchmark file, a TensorBoard event
    file, a Snakemake marker)."""
    results = root / "results"
    io.write_csv(results / "m/metrics.csv", pd.DataFrame({"model": ["a"], "value": [1.0]}))
    for frame in range(3):
        plane = np.zeros((2, 2), np.float32)
        io.write_exr(results / f"m/test/frame_{frame:04d}.exr", {"P.x": plane, "N.x": plane})
    io.save_npz(results / "m/sequence.npz", rest=np.zeros(3), frames=np.ones(2))
    (results / "m/viewer.json").write_text(json.dumps({"kind": "frames", "data": []}))
    io.write_png(results / "m/figure.png", np.zeros((2, 2), np.uint8))
    for other in (
        "logs/m/job.log",
        "benchmarks/m/job.tsv",
        "tensorboard/m/events.out.tfevents.1.vm.2.0",
    ):
        (results / other).parent.mkdir(parents=True, exist_ok=True)
        (results / other).write_text("x")
    (results / "m/.snakemake_timestamp").write_text("")
    return results


def test_a_run_is_described_by_pattern_count_and_field(tmp_path):
    table = output_manifest.describe(_run(tmp_path))
    rows = set(table.itertuples(index=False, name=None))
    assert rows == {
        ("m/metrics.csv", 1, "model"),
        ("m/metrics.csv", 1, "value"),
        ("m/test/frame_*.exr", 3, "N.x"),
        ("m/test/frame_*.exr", 3, "P.x"),
        ("m/sequence.npz", 1, "rest"),
        ("m/sequence.npz", 1, "frames"),
        ("m/viewer.json", 1, "kind"),
        ("m/viewer.json", 1, "data"),
        ("m/figure.png", 1, ""),
    }


def test_a_run_passes_the_check_against_its_own_manifest(tmp_path):
    results = _run(tmp_path)
    output_manifest.write(results, tmp_path / "manifest.csv")
    assert output_manifest.differences(results, tmp_path / "manifest.csv") == []


def test_every_difference_is_named(tmp_path):
    results = _run(tmp_path)
    manifest = tmp_path / "manifest.csv"
    output_manifest.write(results, manifest)
    (results / "m/test/frame_0002.exr").unlink()
    io.write_csv(results / "m/metrics.csv", pd.DataFrame({"model": ["a"], "score": [1.0]}))
    (results / "m/extra.csv").write_text("a\n1\n")
    assert output_manifest.differences(results, manifest) == [
        f"{results / 'm/metrics.csv'}: lacks fields ['value'], has fields not listed ['score']",
        "m/test/frame_*.exr: 2 files, the manifest expects 3",
        f"{results / 'm/extra.csv'}: not in the manifest (m/extra.csv)",
    ]


def test_a_table_with_only_its_header_fails(tmp_path):
    results = _run(tmp_path)
    output_manifest.write(results, tmp_path / "manifest.csv")
    (results / "m/metrics.csv").write_text("model,value\n")
    found = output_manifest.differences(results, tmp_path / "manifest.csv")
    assert found == [f"{results / 'm/metrics.csv'}: no data row under its header"]


def test_a_numbered_set_whose_files_differ_is_refused_naming_both(tmp_path):
    results = _run(tmp_path)
    plane = np.zeros((2, 2), np.float32)
    io.write_exr(results / "m/test/frame_0001.exr", {"P.x": plane})
    with pytest.raises(ValueError, match=r"frame_0001\.exr and .*frame_0000\.exr"):
        output_manifest.describe(results)


def test_an_unreadable_file_is_named(tmp_path):
    results = _run(tmp_path)
    (results / "m/sequence.npz").write_bytes(b"not a zip")
    with pytest.raises(OSError, match=r"sequence\.npz"):
        output_manifest.describe(results)


def test_the_command_line_exits_1_on_a_difference_and_says_how_to_rewrite(tmp_path, capsys):
    results = _run(tmp_path)
    manifest = tmp_path / "manifest.csv"
    assert output_manifest.main(["write", str(results), str(manifest)]) == 0
    assert output_manifest.main(["check", str(results), str(manifest)]) == 0
    (results / "m/figure.png").unlink()
    assert output_manifest.main(["check", str(results), str(manifest)]) == 1
    err = capsys.readouterr().err
    assert "m/figure.png: 0 files, the manifest expects 1" in err
    assert f"python -m neurender.output_manifest write {results} {manifest}" in err


def test_the_smoke_manifest_lists_every_file_the_smoke_report_shows():
    """The committed manifest CI checks the smoke run against names every table, figure
    and viewer each method's record gives the report under the smoke config."""
    smoke = plan.load_config([str(ROOT / "config/smoke.yaml")])
    listed = set(
        io.read_csv(SMOKE_MANIFEST, output_manifest.COLUMNS, ("pattern", "field"))["pattern"]
    )
    for method in methods.METHODS:
        inputs = method.report_inputs(smoke)
        for path in (*inputs.tables, *inputs.figures, *inputs.viewers):
            rel = Path(path).relative_to("results")
            assert output_manifest.pattern_of(rel) in listed, path
