"""Committed studies (:class:`neurender.method.Study`): a view pivots its tidy CSV as
declared, averaging the rows that share a cell; a bad CSV or sidecar fails naming the file
and what was expected; every declared study's files are committed and its view is not
empty; the report shows each study in its method's section with its title and commits."""

import dataclasses
import json
import re
from pathlib import Path

import pandas as pd
import pytest

from neurender import methods
from neurender.method import Study
from neurender.report import build

ROOT = Path(__file__).resolve().parents[1]
COMMIT = "0123456789abcdef0123456789abcdef01234567"


def _study(tmp_path, rows, sidecar=None, **view) -> Study:
    """A study of ``rows`` (a tidy CSV) under ``tmp_path``, its sidecar ``sidecar``."""
    pd.DataFrame(rows).to_csv(tmp_path / "s.csv", index=False)
    record = {"command": "python study.py", "commit": COMMIT, "dirty": False}
    (tmp_path / "s.json").write_text(json.dumps(record if sidecar is None else sidecar))
    return Study(csv="s.csv", title="Toy study", description="A toy.", **view)


def _tidy():
    rows = []
    for seed in (0, 1, 2):
        for model in ("b", "a"):
            for split in ("val", "test"):
                value = 10 * seed + (model == "a") + 100 * (split == "test")
                rows.append(dict(model=model, split=split, seed=seed, metric="m", value=value))
    rows.append(dict(model="a", split="test", seed=0, metric="other", value=-1e3))
    return rows


def test_a_view_pivots_as_declared_averaging_duplicates(tmp_path):
    rows = _tidy()
    study = _study(tmp_path, rows, query="metric == 'm'", index=("model",), columns=("split",))
    view = study.view(tmp_path)
    assert list(view.columns) == ["model", "val", "test"]  # order of appearance
    assert list(view.model) == ["b", "a"]
    frame = pd.DataFrame(rows)
    frame = frame[frame.metric == "m"]
    for row in view.itertuples():
        for split in ("val", "test"):
            mine = frame[(frame.model == row.model) & (frame.split == split)].value
            assert len(mine) == 3  # the three seeds, averaged into one cell
            assert getattr(row, split) == pytest.approx(mine.mean())


def test_a_view_of_numbered_columns_names_them(tmp_path):
    rows = [dict(model="a", epochs=e, metric=m, value=e) for e in (3, 8) for m in ("x", "y")]
    study = _study(tmp_path, rows, index=("model",), columns=("metric", "epochs"))
    view = study.view(tmp_path)
    # the first of the declared columns varies slowest
    named = ["model", "x, epochs 3", "x, epochs 8", "y, epochs 3", "y, epochs 8"]
    assert list(view.columns) == named
    assert view.iloc[0, 1:].tolist() == [3, 8, 3, 8]


def test_a_view_without_columns_has_one_column_of_values(tmp_path):
    rows = [dict(part="p", threads=t, ms=t * 2.0) for t in (1, 2)]
    view = _study(tmp_path, rows, index=("part",), values="ms").view(tmp_path)
    assert list(view.columns) == ["part", "ms"] and view.ms.tolist() == [3.0]


def test_a_missing_column_fails_naming_the_file_and_the_column(tmp_path):
    study = _study(tmp_path, _tidy(), index=("model", "object"), columns=("split",))
    with pytest.raises(ValueError, match=r"s\.csv: no column \['object'\]; .*needs columns"):
        study.view(tmp_path)
    study = _study(tmp_path, _tidy(), index=("model",), values="seconds")
    with pytest.raises(ValueError, match=r"s\.csv: no column \['seconds'\]"):
        study.view(tmp_path)
    study = _study(tmp_path, _tidy(), index=("seed",), values="split")
    with pytest.raises(ValueError, match=r"s\.csv: column 'split' is not numeric"):
        study.view(tmp_path)


def test_an_unreadable_csv_fails_naming_the_file(tmp_path):
    study = _study(tmp_path, _tidy(), index=("model",))
    (tmp_path / "s.csv").write_text("")
    with pytest.raises(ValueError, match=r"s\.csv: not a CSV table"):
        study.view(tmp_path)
    (tmp_path / "s.csv").unlink()
    with pytest.raises(FileNotFoundError, match=r"s\.csv"):
        study.view(tmp_path)


def test_a_query_that_selects_nothing_or_fails_names_the_file(tmp_path):
    study = _study(tmp_path, _tidy(), query="metric == 'none'", index=("model",))
    with pytest.raises(ValueError, match=r"s\.csv: no rows match query"):
        study.view(tmp_path)
    study = _study(tmp_path, _tidy(), query="family == 'test'", index=("model",))
    with pytest.raises(ValueError, match=r"s\.csv: query \"family == 'test'\" failed"):
        study.view(tmp_path)


def test_a_malformed_sidecar_fails_naming_the_file_and_key(tmp_path):
    study = _study(tmp_path, _tidy(), sidecar={"command": "python study.py"}, index=("model",))
    with pytest.raises(ValueError, match=r"s\.json: 'commit' = None; expected a git commit"):
        study.runs(tmp_path)
    runs = {"note": "n", "runs": [{"command": "a", "commit": COMMIT}, {"commit": COMMIT}]}
    study = _study(tmp_path, _tidy(), sidecar=runs, index=("model",))
    with pytest.raises(ValueError, match=r"s\.json: run 1: 'command' = None"):
        study.runs(tmp_path)
    (tmp_path / "s.json").write_text("{not json")
    with pytest.raises(ValueError, match=r"s\.json: not JSON"):
        study.runs(tmp_path)


def test_a_sidecar_of_several_runs_gives_each_runs_command_and_commit(tmp_path):
    runs = [
        {"command": "python a.py", "commit": COMMIT, "dirty": True, "note": "stopped"},
        {"command": "python b.py", "commit": "fedcba9876543210" * 2 + "fedcba98"},
    ]
    study = _study(tmp_path, _tidy(), sidecar={"note": "merged", "runs": runs}, index=("model",))
    note, found = study.runs(tmp_path)
    assert note == "merged"
    assert [(r["command"], r["commit"], r["dirty"]) for r in found] == [
        ("python a.py", COMMIT, True),
        ("python b.py", runs[1]["commit"], None),
    ]
    assert found[0]["note"] == "stopped" and found[1]["note"] == ""


def test_every_declared_study_is_committed_and_its_view_is_not_empty():
    declared = [s for m in methods.METHODS for s in m.studies]
    assert declared  # the built-in methods declare some
    for study in declared:
        assert (ROOT / study.csv).is_file() and (ROOT / study.sidecar).is_file(), study.csv
        assert study.csv.startswith("benchmarks/results/"), study.csv
        view = study.view(ROOT)
        assert len(view) and view.drop(columns=list(study.index)).notna().any().any()
        _, runs = study.runs(ROOT)
        assert runs, study.sidecar


def _section(html: str, key: str) -> str:
    return html.split(f'<h2 id="{key}">', 1)[1].split("<h2 ", 1)[0]


def test_the_report_shows_each_study_in_its_methods_section_with_its_commits(tmp_path):
    out = tmp_path / "r.html"
    build.build_report([], [], out, root=ROOT)
    html = out.read_text()
    for method in methods.METHODS:
        section = _section(html, method.key)
        assert ("Committed studies (not this run)" in section) == bool(method.studies)
        for study in method.studies:
            assert f"<h4>{study.title}</h4>" in section, study.title
            for run in study.runs(ROOT)[1]:
                assert f"<code>{build.commit_label(run)}</code>" in section
    build.build_report([], [], out)  # without a root: no studies
    assert "Committed studies" not in out.read_text()


def test_a_registered_methods_study_reaches_its_section_with_its_numbers(tmp_path, monkeypatch):
    rows = [dict(model="a", split="test", metric="m", value=v) for v in (0.25, 0.75)]
    sidecar = {"command": "python study.py", "commit": COMMIT, "dirty": True}
    study = _study(tmp_path, rows, sidecar=sidecar, index=("model",), columns=("split",))
    # the last method gets the toy study, the others none (their files are not here)
    *others, last = (dataclasses.replace(m, studies=()) for m in methods.METHODS)
    own = dataclasses.replace(last, studies=(study,))
    monkeypatch.setattr(methods, "METHODS", (*others, own))
    build.build_report([], [], tmp_path / "r.html", root=tmp_path)
    section = _section((tmp_path / "r.html").read_text(), own.key)
    assert "<h4>Toy study</h4>" in section and "<p>A toy.</p>" in section
    assert "<code>0123456789ab + uncommitted changes</code>" in section
    assert re.search(r"<td>a</td>\s*<td>0.5</td>", section)  # the mean of 0.25 and 0.75
    (tmp_path / "s.csv").write_text("model,value\na,1\n")
    with pytest.raises(ValueError, match=r"s\.csv: no column \['split'\]"):
        build.build_report([], [], tmp_path / "r.html", root=tmp_path)


def test_a_studys_cells_have_its_significant_digits(tmp_path):
    rows = [dict(model="a", split=s, value=v) for s, v in (("x", 1 / 3), ("y", 2 / 3))]
    study = _study(tmp_path, rows, index=("model",), columns=("split",), digits=2)
    shown = build._study(study, tmp_path)["html"]
    assert "<td>0.33</td>" in shown and "<td>0.67</td>" in shown and "0.333" not in shown
