"""Figures the docs quote are the figures of the files they come from.

``docs/quoted_figures.csv`` lists each quoted figure: the page, the text as it reads there
(a Python format template of the figures, e.g. ``NDR {ours:.3f}``), and where the figures
lie: a committed CSV, the pandas query selecting its one row and the columns (``;`` between
them; the template's fields), or a committed JSON sidecar and the dotted key (the field
``value``). A figure that disagrees with its file, a query that does
not select one row and a README headline number that is not listed all fail.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pandas as pd
import pytest
from test_readme import _methods_table

ROOT = Path(__file__).resolve().parents[1]
REGISTRY = ROOT / "docs" / "quoted_figures.csv"
COLUMNS = ["page", "text", "file", "row", "column"]
_NUMBER = re.compile(r"(?<![\w.])\d+(?:\.\d+)?")


def _figures() -> pd.DataFrame:
    return pd.read_csv(REGISTRY, keep_default_na=False, dtype=str)


def _flat(text: str) -> str:
    """Markdown text with line breaks and runs of blanks as single spaces."""
    return re.sub(r"\s+", " ", text)


def values_of(file: Path, row: str, columns: str) -> dict[str, float]:
    """The figures in ``file`` by field name: for a CSV, ``columns`` (``;`` between them)
    of the one row ``row`` (a pandas query) selects; for a JSON file, the dotted key
    ``row`` as ``value`` (``columns`` empty)."""
    if file.suffix == ".json":
        node = json.loads(file.read_text())
        for key in row.split("."):
            node = node[key]
        return {"value": float(node)}
    table = pd.read_csv(file)
    selected = table.query(row)
    if len(selected) != 1:
        raise ValueError(f"{file}: query {row!r} selects {len(selected)} rows; expected one")
    return {c: float(selected[c].iloc[0]) for c in columns.split(";")}


def test_values_of_reads_one_csv_rows_columns_and_a_dotted_json_key(tmp_path):
    csv = tmp_path / "t.csv"
    csv.write_text("method,label,ours,paper\nndr,a,0.25,1\nndr,b,2.5,3\n")
    assert values_of(csv, "label == 'b'", "ours;paper") == {"ours": 2.5, "paper": 3.0}
    with pytest.raises(ValueError, match="selects 2 rows"):
        values_of(csv, "method == 'ndr'", "ours")
    sidecar = tmp_path / "t.json"
    sidecar.write_text('{"whole_run": {"wall_min": 61.5}}')
    assert values_of(sidecar, "whole_run.wall_min", "") == {"value": 61.5}


def test_registry_has_its_columns_and_names_committed_files():
    figures = _figures()
    assert list(figures.columns) == COLUMNS
    for f in figures.itertuples():
        assert (ROOT / f.page).is_file(), f.page
        assert (ROOT / f.file).is_file(), f.file
        fields = f.column.split(";") if f.column else ["value"]
        assert all("{" + field in f.text for field in fields), f.text


@pytest.mark.parametrize("index", range(len(_figures())))
def test_quoted_figure_reads_as_its_file_gives_it(index):
    f = _figures().iloc[index]
    quoted = f.text.format(**values_of(ROOT / f.file, f.row, f.column))
    page = _flat((ROOT / f.page).read_text(encoding="utf-8"))
    assert _flat(quoted) in page, f"{f.page} should read {quoted!r} ({f.file}: {f.row})"


def test_every_number_in_the_readme_headlines_is_a_listed_figure():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    rows = _methods_table(readme)
    column = [c.lower() for c in rows[0]].index("headline")
    figures = _figures()
    quoted = [
        f.text.format(**values_of(ROOT / f.file, f.row, f.column))
        for f in figures[figures.page == "README.md"].itertuples()
    ]
    for row in rows[1:]:
        cell = re.sub(r"\[[^\]]*\]\([^)]*\)", "", row[column])  # links' text and targets
        for number in _NUMBER.findall(cell):
            assert any(number in q for q in quoted), (
                f"README headline number {number} ({row[0][:30]}...) is in no listed figure"
            )
