import pandas as pd

from neurender import compare, io, provenance


def _run(root, commit, torch_version, value=1.0, timing=0.5):
    io.write_csv(root / "prt" / "metrics.csv", pd.DataFrame({"metric": ["ssim"], "value": [value]}))
    io.write_csv(root / "prt" / "timing.csv", pd.DataFrame({"a": [1], "seconds": [timing]}))
    io.write_csv(root / "tensorboard" / "x.csv", pd.DataFrame({"wall": [timing]}))
    record = {
        "git": {"commit": commit, "dirty": False},
        "packages": {"torch": torch_version},
        "config": {"seed": 0},
        "started": f"2026-01-01T00:00:0{int(timing)}+00:00",
        "finished": "2026-01-01T01:00:00+00:00",
    }
    provenance.write(root / "provenance.json", record)
    return root


def test_main_prints_the_provenance_difference_before_any_output(tmp_path, capsys):
    first = _run(tmp_path / "a", "a" * 40, "2.13.0")
    second = _run(tmp_path / "b", "b" * 40, "2.14.0", timing=3.0)
    assert compare.main([str(first), str(second)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[:3] == [
        "provenance:",
        f"  git.commit: {'a' * 40} -> {'b' * 40}",
        "  packages.torch: 2.13.0 -> 2.14.0",
    ]
    assert lines[3:] == [
        "identical: 1 files",
        "timing only: 1 files",
        "  prt/timing.csv",
        "differs: 0 files",
        "missing: 0 files",
    ]  # the tensorboard folder's CSV, whose values differ, is not compared


def test_runs_of_one_provenance_say_so_and_a_missing_file_is_named(tmp_path):
    first = _run(tmp_path / "a", "a" * 40, "2.13.0")
    second = _run(tmp_path / "b", "a" * 40, "2.13.0", timing=2.0)  # other times only
    assert compare.provenance_lines(first, second) == ["same commit, packages and config"]
    (second / "provenance.json").unlink()
    assert compare.provenance_lines(first, second) == [
        f"no provenance file: {second / 'provenance.json'}"
    ]


def test_a_differing_result_fails_whatever_the_provenance(tmp_path):
    first = _run(tmp_path / "a", "a" * 40, "2.13.0")
    second = _run(tmp_path / "b", "a" * 40, "2.13.0", value=2.0)
    assert compare.main([str(first), str(second)]) == 1
    assert compare.compare_results(first, second)["differs"] == ["prt/metrics.csv"]
